"""Tests of addon/bake/pc2.py: the PC2 format, crash-safe parts, resuming and merging (no Blender).

Run all:   ./build.sh test   (or: /usr/bin/python3 -m unittest discover -s tests/python)
Run one:   /usr/bin/python3 -m unittest -v test_pc2.TestMerge.test_out_of_order   (from tests/python)
"""

import json
import os
import resource
import signal
import shutil
import struct
import subprocess
import sys
import tempfile
import unittest
from array import array

HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.dirname(os.path.dirname(HERE))
PC2_PATH = os.path.join(REPO, "addon", "bake", "pc2.py")


def load_pc2():
    """addon/bake/pc2.py by its path (putting addon/bake on sys.path would let its operator.py shadow the
    standard library's operator module)."""
    import importlib.util
    spec = importlib.util.spec_from_file_location("pc2", PC2_PATH)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


pc2 = load_pc2()

IDENTITY = {"object": "Thing", "vertices": 3, "source": "sha256:abc", "blender": "test", "addon": "0"}


def read_bytes(path):
    with open(path, "rb") as file:
        return file.read()


def frame_values(frame, points=3):
    """Distinct, exactly representable float32 values for a frame."""
    return array('f', [frame * 1000.0 + index * 0.25 for index in range(3 * points)])


class TempDir(unittest.TestCase):

    def setUp(self):
        self.directory = tempfile.mkdtemp(prefix="lvp-pc2-")
        self.addCleanup(shutil.rmtree, self.directory, True)
        self.final = os.path.join(self.directory, "Thing.pc2")

    def bake_part(self, first, last, identity=IDENTITY, finish=True):
        writer = pc2.PartWriter(self.final, identity, 3, first)
        for frame in range(first, last + 1):
            writer.append(frame, frame_values(frame))
        if finish:
            return writer.finish()
        writer.close()
        return writer


class TestFormat(TempDir):

    def test_header_layout(self):
        header = pc2.pack_header(5, 10.0, 1.0, 7)
        self.assertEqual(len(header), 32)
        self.assertEqual(header[:12], b"POINTCACHE2\0")
        self.assertEqual(struct.unpack("<iiffi", header[12:]), (1, 5, 10.0, 1.0, 7))

    def test_round_trip(self):
        samples = [frame_values(frame) for frame in range(4, 9)]
        pc2.write_pc2(self.final, samples, start_frame=4)
        header, read = pc2.read_pc2(self.final)
        self.assertEqual((header.version, header.num_points, header.start_frame, header.sample_rate,
                          header.num_samples), (1, 3, 4.0, 1.0, 5))
        self.assertEqual(read, samples)
        self.assertEqual(os.path.getsize(self.final), 32 + 5 * 3 * 12)
        self.assertEqual(pc2.read_sample(self.final, 2), samples[2])
        with open(self.final, "rb") as file:
            file.seek(32)
            self.assertEqual(struct.unpack("<3f", file.read(12)), (4000.0, 4000.25, 4000.5))

    def test_truncated_file_is_refused(self):
        pc2.write_pc2(self.final, [frame_values(1), frame_values(2)], start_frame=1)
        with open(self.final, "r+b") as file:
            file.truncate(40)
        with self.assertRaises(pc2.PC2Error):
            pc2.read_pc2(self.final)
        with open(self.final, "wb") as file:
            file.write(b"not a cache at all, nothing")
        with self.assertRaisesRegex(pc2.PC2Error, "not a PC2 file"):
            pc2.read_header(self.final)

    def test_atomic_write_leaves_nothing_on_error(self):
        pc2.write_pc2(self.final, [frame_values(1)], start_frame=1)
        before = read_bytes(self.final)
        with self.assertRaises(RuntimeError):
            with pc2.AtomicFile(self.final) as out:
                out.write(b"half a file")
                raise RuntimeError("killed")
        self.assertEqual(read_bytes(self.final), before)
        self.assertEqual(os.listdir(self.directory), ["Thing.pc2"])


class TestFrames(unittest.TestCase):

    def test_parse(self):
        self.assertEqual(pc2.parse_frames("1-5"), [1, 2, 3, 4, 5])
        self.assertEqual(pc2.parse_frames("7"), [7])
        self.assertEqual(pc2.parse_frames("1-3, 6..7"), [1, 2, 3, 6, 7])
        self.assertEqual(pc2.parse_frames("-2-1"), [-2, -1, 0, 1])
        self.assertEqual(pc2.parse_frames("-5--3"), [-5, -4, -3])

    def test_errors_say_what(self):
        with self.assertRaisesRegex(pc2.PC2Error, "empty"):
            pc2.parse_frames("  ")
        with self.assertRaisesRegex(pc2.PC2Error, "reversed"):
            pc2.parse_frames("10-1")
        with self.assertRaisesRegex(pc2.PC2Error, "cannot read"):
            pc2.parse_frames("a-b")

    def test_format_and_split(self):
        self.assertEqual(pc2.format_frames([1, 2, 3, 7, 9, 10]), "1-3,7,9-10")
        self.assertEqual(pc2.split_even(list(range(1, 11)), 3), [[1, 2, 3], [4, 5, 6], [7, 8, 9, 10]])
        self.assertEqual(pc2.split_even([1, 2], 5), [[1], [2]])


class TestParts(TempDir):

    def test_complete_part_is_a_valid_pc2(self):
        path = self.bake_part(3, 6)
        header, samples = pc2.read_pc2(path)
        self.assertEqual((header.start_frame, header.num_samples), (3.0, 4))
        self.assertEqual(samples, [frame_values(frame) for frame in range(3, 7)])

    def test_partial_part_keeps_finished_frames(self):
        writer = self.bake_part(1, 4, finish=False)
        # A killed process: half a frame written after the last journal line, and half a journal line.
        with open(writer.partial_path, "ab") as file:
            file.write(b"\1" * 17)
        with open(writer.journal_path, "ab") as file:
            file.write(b"5")
        parts, stale = pc2.scan_parts(self.final, IDENTITY)
        self.assertEqual(stale, [])
        self.assertEqual([(part.first, part.count, part.complete) for part in parts], [(1, 4, False)])
        # Blender's reader refuses a 0-sample header, so a partial part never passes for a cache.
        self.assertEqual(pc2.read_header(writer.partial_path).num_samples, 0)

    def test_journal_shorter_than_data_wins(self):
        writer = self.bake_part(1, 3, finish=False)
        with open(writer.journal_path, "r+b") as file:
            lines = file.read().split(b"\n")
            file.seek(0)
            file.truncate()
            file.write(b"\n".join(lines[:2]) + b"\n")  # header + frame 1 only
        parts, _ = pc2.scan_parts(self.final, IDENTITY)
        self.assertEqual([(part.first, part.count) for part in parts], [(1, 1)])

    def test_other_identity_is_stale(self):
        self.bake_part(1, 2, identity=dict(IDENTITY, source="sha256:other"))
        parts, stale = pc2.scan_parts(self.final, IDENTITY)
        self.assertEqual(parts, [])
        self.assertEqual(len(stale), 2)

    def test_resume_plans_only_missing_frames(self):
        self.bake_part(1, 4)
        self.bake_part(8, 9, finish=False)
        parts, _ = pc2.scan_parts(self.final, IDENTITY)
        self.assertEqual(pc2.missing_frames(range(1, 11), parts), [5, 6, 7, 10])

    def test_sync_happens(self):
        ticks = iter(range(100))
        writer = pc2.PartWriter(self.final, IDENTITY, 3, 1, sync_seconds=2, clock=lambda: next(ticks))
        for frame in range(1, 5):
            writer.append(frame, frame_values(frame))
        self.assertGreater(writer._last_sync, 0)
        writer.finish()

    def test_frames_must_come_in_order(self):
        writer = pc2.PartWriter(self.final, IDENTITY, 3, 1)
        self.addCleanup(writer.close)
        with self.assertRaises(pc2.PC2Error):
            writer.append(2, frame_values(2))


class TestMerge(TempDir):

    def merged(self):
        return pc2.read_pc2(self.final)

    def test_out_of_order(self):
        # Chunks finished in any order, one of them still partial, one overlapping another.
        self.bake_part(21, 30)
        self.bake_part(1, 10)
        self.bake_part(11, 17, finish=False)
        self.bake_part(15, 20)
        parts, _ = pc2.scan_parts(self.final, IDENTITY)
        pc2.merge(parts, 1, 30, self.final, 3, record={"identity": IDENTITY})
        header, samples = self.merged()
        self.assertEqual((header.start_frame, header.num_samples, header.num_points), (1.0, 30, 3))
        self.assertEqual(samples, [frame_values(frame) for frame in range(1, 31)])
        with open(pc2.sidecar_path(self.final)) as file:
            record = json.load(file)
        self.assertEqual((record["frame_start"], record["frame_end"], record["identity"]), (1, 30, IDENTITY))

    def test_missing_frames_refused_and_nothing_written(self):
        self.bake_part(1, 5)
        self.bake_part(8, 10)
        parts, _ = pc2.scan_parts(self.final, IDENTITY)
        with self.assertRaises(pc2.MissingFramesError) as caught:
            pc2.merge(parts, 1, 10, self.final, 3)
        self.assertEqual(caught.exception.missing, [6, 7])
        self.assertIn("6-7", str(caught.exception))
        self.assertFalse(os.path.exists(self.final))

    def test_merged_file_is_reused_as_a_part(self):
        self.bake_part(1, 5)
        parts, _ = pc2.scan_parts(self.final, IDENTITY)
        pc2.merge(parts, 1, 5, self.final, 3, record={"identity": IDENTITY})
        pc2.remove_parts_directory(self.final)
        parts, _ = pc2.scan_parts(self.final, IDENTITY)
        self.assertEqual(pc2.missing_frames(range(1, 8), parts), [6, 7])
        self.assertEqual(pc2.scan_parts(self.final, dict(IDENTITY, source="x"))[0], [])
        self.bake_part(6, 7)
        parts, _ = pc2.scan_parts(self.final, IDENTITY)
        pc2.merge(parts, 1, 7, self.final, 3, record={"identity": IDENTITY})
        self.assertEqual(self.merged()[1], [frame_values(frame) for frame in range(1, 8)])

    def test_disk_full_during_merge_keeps_old_file_and_parts(self):
        pc2.write_pc2(self.final, [frame_values(0)], start_frame=0)
        before = read_bytes(self.final)
        self.bake_part(1, 40)
        parts, _ = pc2.scan_parts(self.final, IDENTITY)
        part_files = sorted(os.listdir(pc2.parts_directory(self.final)))
        limit = os.path.getsize(parts[0].path) // 2
        code = ("import importlib.util, sys\n"
                "spec = importlib.util.spec_from_file_location('pc2', %r)\n"
                "pc2 = importlib.util.module_from_spec(spec); spec.loader.exec_module(pc2)\n"
                "parts, _ = pc2.scan_parts(%r, %r)\n"
                "try:\n    pc2.merge(parts, 1, 40, %r, 3)\n"
                "except pc2.DiskFullError as error:\n    print(error); sys.exit(3)\n"
                % (PC2_PATH, self.final, IDENTITY, self.final))

        def limit_file_size():
            signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
            resource.setrlimit(resource.RLIMIT_FSIZE, (limit, limit))

        completed = subprocess.run([sys.executable, "-c", code], preexec_fn=limit_file_size,
                                   stdout=subprocess.PIPE, stderr=subprocess.STDOUT, universal_newlines=True)
        self.assertEqual(completed.returncode, 3, completed.stdout)
        self.assertIn("file size limit", completed.stdout)
        self.assertEqual(read_bytes(self.final), before)
        self.assertEqual(sorted(os.listdir(pc2.parts_directory(self.final))), part_files)
        self.assertEqual(sorted(name for name in os.listdir(self.directory) if ".tmp-" in name), [])


class TestWritableDirectory(TempDir):

    def test_a_file_in_the_way(self):
        blocker = os.path.join(self.directory, "file")
        open(blocker, "w").close()
        with self.assertRaisesRegex(pc2.PC2Error, "cannot create the output directory"):
            pc2.check_writable_directory(os.path.join(blocker, "cache"))

    def test_creates_it(self):
        target = os.path.join(self.directory, "a", "b")
        pc2.check_writable_directory(target)
        self.assertEqual(os.listdir(target), [])


if __name__ == "__main__":
    unittest.main()
