# SPDX-License-Identifier: GPL-3.0-or-later
"""PC2 point caches: the file format, crash-safe part files, and merging parts into one file.

Pure Python (no bpy, no numpy), so it runs and is tested with any Python 3 (tests/python/test_pc2.py).

The format (the one Blender's Mesh Cache modifier, Maya, 3ds Max and Houdini read), little-endian:

    char[12]  "POINTCACHE2\\0"
    int32     version, 1
    int32     num_points
    float32   start_frame
    float32   sample_rate     (frames between two samples; 1.0 here)
    int32     num_samples     (Blender rejects a file with 0)
    float32   x y z per point, per sample: num_samples * num_points * 12 bytes

A bake writes parts, then merges them (see docs/baking.md):

    OUT/Name.pc2.parts/<first>-<last>.<token>.journal    one per run of consecutive frames: a JSON
                                                        header line (identity, first, points), then one
                                                        line per frame whose data is fully written
    OUT/Name.pc2.parts/<first>-<last>.<token>.pc2.partial   the frames so far, after a PC2 header that
                                                        says 0 samples (no reader takes it for a cache)
    OUT/Name.pc2.parts/<first>-<last>.<token>.pc2       the same part once complete: a valid PC2 file
    OUT/Name.pc2 and OUT/Name.pc2.json                  the merged cache and what it was baked from

A frame counts as baked when its data is written and its journal line follows it (both written with
os.write, so a killed process loses nothing it finished; data and journal are fsynced every few seconds
and when a part completes, so a power cut loses at most those seconds). Parts of different processes
never share a file, so chunks may run at the same time on several machines. A part only counts for a
bake with the same identity (object, vertex count, the .blend's SHA-256, Blender and add-on versions).

Every final file is written next to its destination under a temporary name, fsynced and renamed
over the destination (os.replace), so a file with the final name is always complete.
"""

import errno
import json
import os
import struct
import sys
import uuid
from array import array

MAGIC = b"POINTCACHE2\0"
VERSION = 1
HEADER = struct.Struct("<12siiffi")
HEADER_SIZE = HEADER.size  # 32
SAMPLES_OFFSET = 28  # where num_samples sits in the header

PARTS_SUFFIX = ".parts"
SIDECAR_SUFFIX = ".json"
PART_FORMAT = 1

# errno values that mean "the disk (or the allowed file size) is full".
FULL_ERRNOS = {errno.ENOSPC, errno.EFBIG, getattr(errno, "EDQUOT", errno.ENOSPC)}


class PC2Error(Exception):
    """A problem with a cache file or the bake's directory, with a message for the user."""


class DiskFullError(PC2Error):
    """The disk ran out of space (or the file size limit was reached) while writing."""


class MissingFramesError(PC2Error):
    """A merge was asked for frames that no part holds."""

    def __init__(self, message, missing):
        super().__init__(message)
        self.missing = missing


# ---- the format ----------------------------------------------------------------------------


def pack_header(num_points, start_frame, sample_rate, num_samples):
    return HEADER.pack(MAGIC, VERSION, num_points, float(start_frame), float(sample_rate), num_samples)


class Header:
    __slots__ = ("version", "num_points", "start_frame", "sample_rate", "num_samples")

    def __init__(self, version, num_points, start_frame, sample_rate, num_samples):
        self.version = version
        self.num_points = num_points
        self.start_frame = start_frame
        self.sample_rate = sample_rate
        self.num_samples = num_samples

    @property
    def frame_size(self):
        return 12 * self.num_points

    def __repr__(self):
        return "Header(points=%d, start=%g, rate=%g, samples=%d)" % (
            self.num_points, self.start_frame, self.sample_rate, self.num_samples)


def unpack_header(data, path="<data>"):
    if len(data) < HEADER_SIZE:
        raise PC2Error("%s is not a PC2 file: %d bytes, shorter than the header" % (path, len(data)))
    magic, version, num_points, start_frame, sample_rate, num_samples = HEADER.unpack(data[:HEADER_SIZE])
    if magic != MAGIC:
        raise PC2Error("%s is not a PC2 file (it does not start with POINTCACHE2)" % path)
    if num_points < 0 or num_samples < 0:
        raise PC2Error("%s has a corrupt PC2 header (%d points, %d samples)" % (path, num_points, num_samples))
    return Header(version, num_points, start_frame, sample_rate, num_samples)


def read_header(path):
    with open(path, "rb") as file:
        return unpack_header(file.read(HEADER_SIZE), path)


def to_bytes(positions):
    """float32 x y z per point (an array('f') or any sequence of numbers) as little-endian bytes."""
    values = positions if isinstance(positions, array) and positions.typecode == 'f' else array('f', positions)
    if sys.byteorder != "little":
        values = array('f', values)
        values.byteswap()
    return values.tobytes()


def from_bytes(data):
    values = array('f')
    values.frombytes(data)
    if sys.byteorder != "little":
        values.byteswap()
    return values


def read_pc2(path):
    """(Header, [array('f') per sample]). Checks that the file holds every sample its header promises."""
    with open(path, "rb") as file:
        header = unpack_header(file.read(HEADER_SIZE), path)
        size = header.frame_size
        samples = []
        for index in range(header.num_samples):
            data = file.read(size)
            if len(data) != size:
                raise PC2Error("%s is truncated: sample %d of %d is missing" % (path, index, header.num_samples))
            samples.append(from_bytes(data))
    return header, samples


def read_sample(path, index):
    """One sample of a PC2 file, array('f') of 3 * num_points."""
    with open(path, "rb") as file:
        header = unpack_header(file.read(HEADER_SIZE), path)
        if not 0 <= index < header.num_samples:
            raise PC2Error("%s has no sample %d (it has %d)" % (path, index, header.num_samples))
        file.seek(HEADER_SIZE + index * header.frame_size)
        data = file.read(header.frame_size)
    if len(data) != header.frame_size:
        raise PC2Error("%s is truncated at sample %d" % (path, index))
    return from_bytes(data)


# ---- writing safely ------------------------------------------------------------------------


def _raise_write_error(error, path):
    if error.errno in FULL_ERRNOS:
        reason = "the file size limit was reached" if error.errno == errno.EFBIG else "the disk is full"
        raise DiskFullError("%s while writing %s (%s)" % (reason, path, os.strerror(error.errno))) from error
    raise PC2Error("cannot write %s: %s" % (path, error.strerror or error)) from error


def write_all(fd, data, path):
    """os.write until every byte is written; a full disk raises DiskFullError."""
    view = memoryview(data)
    try:
        while view:
            written = os.write(fd, view)
            if written <= 0:
                raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
            view = view[written:]
    except OSError as error:
        _raise_write_error(error, path)


def fsync_directory(directory):
    try:
        fd = os.open(directory, os.O_RDONLY | getattr(os, "O_DIRECTORY", 0))
    except OSError:
        return
    try:
        os.fsync(fd)
    except OSError:
        pass
    finally:
        os.close(fd)


def temporary_name(path):
    """A hidden name next to path that never ends with the final name's extension."""
    directory, name = os.path.split(path)
    return os.path.join(directory, ".%s.tmp-%s" % (name, uuid.uuid4().hex[:12]))


class AtomicFile:
    """Writes a file under a temporary name and renames it over path only when everything was written and
    fsynced; on any error (or an exception in the with block) the temporary file is removed.

        with AtomicFile(path) as out:
            out.write(data)
    """

    def __init__(self, path):
        self.path = path
        self.temporary = temporary_name(path)
        self.fd = None

    def __enter__(self):
        try:
            self.fd = os.open(self.temporary, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o644)
        except OSError as error:
            _raise_write_error(error, self.path)
        return self

    def write(self, data):
        write_all(self.fd, data, self.path)

    def __exit__(self, kind, value, traceback):
        try:
            if kind is None:
                try:
                    os.fsync(self.fd)
                except OSError as error:
                    _raise_write_error(error, self.path)
                os.close(self.fd)
                self.fd = None
                os.replace(self.temporary, self.path)
                fsync_directory(os.path.dirname(os.path.abspath(self.path)))
        finally:
            if self.fd is not None:
                os.close(self.fd)
            if os.path.exists(self.temporary):
                os.unlink(self.temporary)
        return False


def write_pc2(path, samples, start_frame, sample_rate=1.0):
    """Writes a whole PC2 file atomically. samples: sequences of 3 * num_points floats, all the same size."""
    samples = list(samples)
    if not samples:
        raise PC2Error("a PC2 file needs at least one sample (%s)" % path)
    num_points = len(samples[0]) // 3
    with AtomicFile(path) as out:
        out.write(pack_header(num_points, start_frame, sample_rate, len(samples)))
        for sample in samples:
            if len(sample) != 3 * num_points:
                raise PC2Error("samples of different sizes for %s" % path)
            out.write(to_bytes(sample))


def write_json(path, value):
    with AtomicFile(path) as out:
        out.write((json.dumps(value, indent=1, sort_keys=True) + "\n").encode("utf-8"))


def check_writable_directory(directory):
    """Creates directory when missing and proves a file can be created in it. Raises PC2Error saying why not."""
    try:
        os.makedirs(directory, exist_ok=True)
    except OSError as error:
        raise PC2Error("cannot create the output directory %s: %s" % (directory, error.strerror or error)) from error
    if not os.path.isdir(directory):
        raise PC2Error("the output path %s is not a directory" % directory)
    probe = os.path.join(directory, ".lvp-write-test-%s" % uuid.uuid4().hex[:12])
    try:
        fd = os.open(probe, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o644)
        try:
            write_all(fd, b"lvp", probe)
        finally:
            os.close(fd)
    except OSError as error:
        raise PC2Error("cannot write in the output directory %s: %s" % (directory, error.strerror or error)) from error
    finally:
        if os.path.exists(probe):
            os.unlink(probe)


# ---- frames --------------------------------------------------------------------------------


def parse_frames(spec):
    """'1-100' or '7' or '1-10,20-30' -> sorted list of distinct frames. Raises PC2Error for an empty,
    malformed or reversed range, naming which."""
    text = (spec or "").strip()
    if not text:
        raise PC2Error("the frame range is empty: give FIRST-LAST, e.g. --frames 1-250")
    frames = set()
    for piece in text.split(","):
        piece = piece.strip()
        if not piece:
            raise PC2Error("the frame range %r has an empty part: give FIRST-LAST, e.g. 1-250" % spec)
        first, last = _parse_range(piece, spec)
        if last < first:
            raise PC2Error("the frame range %s is reversed (%d comes after %d): give FIRST-LAST with FIRST <= LAST"
                           % (piece, first, last))
        frames.update(range(first, last + 1))
    return sorted(frames)


def _parse_range(piece, spec):
    # "A", "A-B", "A..B"; A and B may be negative ("-10--5").
    for separator in ("..", ":"):
        if separator in piece:
            first, _, last = piece.partition(separator)
            return _int(first, spec), _int(last, spec)
    start = 1 if piece.startswith("-") else 0
    index = piece.find("-", start)
    if index < 0:
        value = _int(piece, spec)
        return value, value
    return _int(piece[:index], spec), _int(piece[index + 1:], spec)


def _int(text, spec):
    try:
        return int(text.strip())
    except ValueError:
        raise PC2Error("cannot read the frame range %r: give FIRST-LAST, e.g. 1-250" % spec) from None


def format_frames(frames):
    """[1, 2, 3, 7, 9, 10] -> '1-3,7,9-10'."""
    return ",".join(str(a) if a == b else "%d-%d" % (a, b) for a, b in runs(frames))


def runs(frames):
    """Consecutive runs of sorted distinct frames as (first, last) pairs."""
    result = []
    for frame in sorted(set(frames)):
        if result and frame == result[-1][1] + 1:
            result[-1][1] = frame
        else:
            result.append([frame, frame])
    return [(first, last) for first, last in result]


def split_even(frames, count):
    """Splits sorted frames into at most count contiguous slices of nearly equal size (no empty slice)."""
    frames = sorted(frames)
    count = max(1, min(count, len(frames)))
    slices = []
    start = 0
    for index in range(count):
        end = start + (len(frames) - start) // (count - index)
        slices.append(frames[start:end])
        start = end
    return [piece for piece in slices if piece]


# ---- parts ---------------------------------------------------------------------------------


def parts_directory(final_path):
    return final_path + PARTS_SUFFIX


def sidecar_path(final_path):
    return final_path + SIDECAR_SUFFIX


class PartWriter:
    """Appends consecutive frames to a new part of the bake of one object (see the top of this file).

    Frames must come in order first, first + 1, ...; finish() makes the part a valid PC2 file.
    """

    def __init__(self, final_path, identity, num_points, first, sync_seconds=2.0, clock=None):
        import time
        self._clock = clock or time.monotonic
        self.directory = parts_directory(final_path)
        self.identity = identity
        self.num_points = num_points
        self.first = first
        self.count = 0
        self.sync_seconds = sync_seconds
        self._last_sync = self._clock()
        base = "%d-%s" % (first, uuid.uuid4().hex[:12])
        self.base = os.path.join(self.directory, base)
        self.partial_path = self.base + ".pc2.partial"
        self.complete_path = self.base + ".pc2"
        self.journal_path = self.base + ".journal"
        self.data_fd = self.journal_fd = None
        try:
            os.makedirs(self.directory, exist_ok=True)
        except OSError as error:
            _raise_write_error(error, self.directory)
        header_line = json.dumps({"lvp_bake_part": PART_FORMAT, "identity": identity, "first": first,
                                  "points": num_points}, sort_keys=True) + "\n"
        try:
            self.data_fd = os.open(self.partial_path, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o644)
            write_all(self.data_fd, pack_header(num_points, first, 1.0, 0), self.partial_path)
            self.journal_fd = os.open(self.journal_path, os.O_WRONLY | os.O_CREAT | os.O_EXCL | os.O_APPEND, 0o644)
            write_all(self.journal_fd, header_line.encode("utf-8"), self.journal_path)
        except OSError as error:
            self.close()
            _raise_write_error(error, self.base)
        except PC2Error:
            self.close()
            raise

    @property
    def next_frame(self):
        return self.first + self.count

    def append(self, frame, positions):
        if frame != self.next_frame:
            raise PC2Error("part %s expects frame %d, got %d" % (self.base, self.next_frame, frame))
        data = to_bytes(positions)
        if len(data) != 12 * self.num_points:
            raise PC2Error("frame %d has %d points, the part has %d" % (frame, len(data) // 12, self.num_points))
        write_all(self.data_fd, data, self.partial_path)
        write_all(self.journal_fd, b"%d\n" % frame, self.journal_path)
        self.count += 1
        if self._clock() - self._last_sync >= self.sync_seconds:
            self.sync()

    def sync(self):
        for fd, path in ((self.data_fd, self.partial_path), (self.journal_fd, self.journal_path)):
            if fd is not None:
                try:
                    os.fdatasync(fd) if hasattr(os, "fdatasync") else os.fsync(fd)
                except OSError as error:
                    _raise_write_error(error, path)
        self._last_sync = self._clock()

    def finish(self):
        """Makes the part a complete PC2 file (or removes it when it holds no frame). Returns its path."""
        if self.count == 0:
            self.close()
            for path in (self.partial_path, self.journal_path):
                if os.path.exists(path):
                    os.unlink(path)
            return None
        try:
            os.pwrite(self.data_fd, struct.pack("<i", self.count), SAMPLES_OFFSET)
        except OSError as error:
            _raise_write_error(error, self.partial_path)
        self.sync()
        self.close()
        os.replace(self.partial_path, self.complete_path)
        fsync_directory(self.directory)
        return self.complete_path

    def close(self):
        """Stops writing; what was written stays (a partial part keeps its finished frames)."""
        for name in ("data_fd", "journal_fd"):
            fd = getattr(self, name)
            if fd is not None:
                try:
                    os.close(fd)
                except OSError:
                    pass
                setattr(self, name, None)


class Part:
    """A part found on disk: frames first .. first + count - 1 at data_offset in path."""

    def __init__(self, path, identity, first, count, num_points, complete, journal=None, data_offset=HEADER_SIZE):
        self.path = path
        self.identity = identity
        self.first = first
        self.count = count
        self.num_points = num_points
        self.complete = complete
        self.journal = journal
        self.data_offset = data_offset

    @property
    def frames(self):
        return range(self.first, self.first + self.count)

    def __repr__(self):
        return "Part(%s, frames %d-%d%s)" % (os.path.basename(self.path), self.first, self.first + self.count - 1,
                                             "" if self.complete else ", partial")


def _read_journal(path):
    """(header dict, frames listed) or (None, []) when the journal is unreadable."""
    try:
        with open(path, "rb") as file:
            data = file.read()
    except OSError:
        return None, []
    lines = data.split(b"\n")
    # Only lines ended by a newline count: the last element is what follows the last newline.
    complete_lines = lines[:-1]
    if not complete_lines:
        return None, []
    try:
        header = json.loads(complete_lines[0].decode("utf-8"))
    except ValueError:
        return None, []
    if not isinstance(header, dict) or header.get("lvp_bake_part") != PART_FORMAT:
        return None, []
    frames = []
    for line in complete_lines[1:]:
        try:
            frames.append(int(line))
        except ValueError:
            break
    return header, frames


def scan_parts(final_path, identity):
    """(parts, stale) of the bake whose final file is final_path: parts with this identity (complete ones,
    the finished frames of partial ones, and the final file itself when its sidecar says it has this
    identity), and the paths of parts from another bake (another .blend, object or version)."""
    parts = []
    stale = []
    directory = parts_directory(final_path)
    names = sorted(os.listdir(directory)) if os.path.isdir(directory) else []
    for name in names:
        if not name.endswith(".journal"):
            continue
        journal = os.path.join(directory, name)
        base = journal[:-len(".journal")]
        header, listed = _read_journal(journal)
        files = [path for path in (base + ".pc2", base + ".pc2.partial") if os.path.exists(path)]
        if header is None or header.get("identity") != identity:
            stale.extend([journal] + files)
            continue
        first = header["first"]
        num_points = header["points"]
        frame_size = 12 * num_points
        if os.path.exists(base + ".pc2"):
            try:
                part_header = read_header(base + ".pc2")
            except (OSError, PC2Error):
                stale.extend([journal] + files)
                continue
            available = (os.path.getsize(base + ".pc2") - HEADER_SIZE) // frame_size if frame_size else 0
            count = min(part_header.num_samples, available)
            parts.append(Part(base + ".pc2", identity, first, count, num_points, True, journal))
        elif os.path.exists(base + ".pc2.partial"):
            count = 0
            for frame in listed:  # the journal lists frames in order from first
                if frame != first + count:
                    break
                count += 1
            available = (os.path.getsize(base + ".pc2.partial") - HEADER_SIZE) // frame_size if frame_size else 0
            count = min(count, max(0, available))
            if count > 0:
                parts.append(Part(base + ".pc2.partial", identity, first, count, num_points, False, journal))
        else:
            stale.append(journal)
    # Orphan data files without a journal cannot be trusted.
    for name in names:
        path = os.path.join(directory, name)
        if name.endswith((".pc2", ".pc2.partial")):
            base = path[:-len(".pc2")] if name.endswith(".pc2") else path[:-len(".pc2.partial")]
            if not os.path.exists(base + ".journal"):
                stale.append(path)
    final = final_part(final_path, identity)
    if final is not None:
        parts.append(final)
    return parts, stale


def final_part(final_path, identity):
    """The merged file as a part, when it exists and its sidecar records this identity."""
    sidecar = sidecar_path(final_path)
    if not (os.path.exists(final_path) and os.path.exists(sidecar)):
        return None
    try:
        with open(sidecar, encoding="utf-8") as file:
            record = json.load(file)
        header = read_header(final_path)
    except (OSError, ValueError, PC2Error):
        return None
    if record.get("identity") != identity or header.sample_rate != 1.0:
        return None
    expected = HEADER_SIZE + header.num_samples * header.frame_size
    if os.path.getsize(final_path) < expected or header.num_samples <= 0:
        return None
    first = int(record.get("frame_start", header.start_frame))
    return Part(final_path, identity, first, header.num_samples, header.num_points, True)


def frames_done(parts):
    done = set()
    for part in parts:
        done.update(part.frames)
    return done


def missing_frames(frames, parts):
    done = frames_done(parts)
    return [frame for frame in frames if frame not in done]


def remove_paths(paths):
    for path in paths:
        try:
            os.unlink(path)
        except FileNotFoundError:
            pass


def remove_parts_directory(final_path):
    """Removes the parts directory of a bake (after a merge). Leaves anything that is not ours."""
    directory = parts_directory(final_path)
    if not os.path.isdir(directory):
        return
    for name in os.listdir(directory):
        if name.endswith((".journal", ".pc2", ".pc2.partial")) or ".tmp-" in name:
            remove_paths([os.path.join(directory, name)])
    try:
        os.rmdir(directory)
    except OSError:
        pass


def merge(parts, first, last, final_path, num_points, record=None, chunk_bytes=8 << 20):
    """Writes frames first..last taken from parts (in any order, overlapping or not) into final_path as one
    PC2 file, atomically, and then its sidecar (record plus the frame range). Raises MissingFramesError
    when some frame is in no part, and DiskFullError when the disk fills (the parts stay).

    Complete parts are preferred over partial ones; otherwise the first part listed wins."""
    if last < first:
        raise PC2Error("the frame range %d-%d is reversed" % (first, last))
    ordered = sorted(parts, key=lambda part: (not part.complete, part.first))
    source = {}
    for part in ordered:
        if part.num_points != num_points:
            raise PC2Error("%s has %d points, the object has %d" % (part.path, part.num_points, num_points))
        for frame in part.frames:
            if first <= frame <= last and frame not in source:
                source[frame] = part
    missing = [frame for frame in range(first, last + 1) if frame not in source]
    if missing:
        raise MissingFramesError("frames %s of %s are not baked yet" % (format_frames(missing),
                                                                       os.path.basename(final_path)), missing)
    frame_size = 12 * num_points
    sidecar = sidecar_path(final_path)
    # The old sidecar goes first: a final file without one is never reused.
    remove_paths([sidecar])
    files = {}
    try:
        with AtomicFile(final_path) as out:
            out.write(pack_header(num_points, first, 1.0, last - first + 1))
            frame = first
            while frame <= last:
                part = source[frame]
                end = frame
                while end + 1 <= last and source[end + 1] is part:
                    end += 1
                if part.path not in files:
                    files[part.path] = open(part.path, "rb")
                handle = files[part.path]
                handle.seek(part.data_offset + (frame - part.first) * frame_size)
                remaining = (end - frame + 1) * frame_size
                while remaining:
                    data = handle.read(min(remaining, chunk_bytes))
                    if not data:
                        raise PC2Error("%s ends before frame %d" % (part.path, end))
                    out.write(data)
                    remaining -= len(data)
                frame = end + 1
    finally:
        for handle in files.values():
            handle.close()
    value = dict(record or {})
    value.update({"frame_start": first, "frame_end": last, "sample_rate": 1.0, "points": num_points,
                  "file": os.path.basename(final_path)})
    write_json(sidecar, value)
    return final_path
