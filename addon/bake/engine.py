# SPDX-License-Identifier: GPL-3.0-or-later
"""One bake in this Blender process: plan what is missing, evaluate frame after frame into parts,
merge the parts into one PC2 file per object. The operator drives it frame by frame (so that Esc can
stop it between two frames) and the command line runs it to the end, or runs several Blender
processes that each bake a slice (command.py).

    bake = Bake(scene, objects, frames, directory, source)
    bake.plan()                 # scans existing parts: only missing frames are baked
    while not bake.done:
        bake.step()             # one frame, all objects
    bake.finish_parts()
    bake.merge()                # OUT/<name>.pc2 (+ .json), parts removed

Stopping anywhere (bake.close()) keeps every finished frame for the next run.
"""

import hashlib
import os
import re
import sys
import time

import bpy

from ..session import SESSION
from . import capture
from . import pc2
from .capture import BakeError


def file_name(object_name):
    """A file name for an object's cache: its name with path separators and control characters replaced."""
    cleaned = re.sub(r'[\x00-\x1f/\\:*?"<>|]', "_", object_name).strip()
    if cleaned in ("", ".", ".."):
        cleaned = "object"
    return cleaned + ".pc2"


def addon_version():
    from .. import _lvp
    return getattr(_lvp, "version", "?")


def file_fingerprint(path):
    """'sha256:<hex>' of a saved .blend: parts baked from another version of the file are never reused."""
    digest = hashlib.sha256()
    with open(path, "rb") as file:
        for block in iter(lambda: file.read(1 << 20), b""):
            digest.update(block)
    return "sha256:" + digest.hexdigest()


def current_source():
    """The fingerprint of what is being baked: the .blend on disk when it is saved and unchanged, else a
    value that matches nothing (an unsaved bake can be cancelled, but never resumed)."""
    path = bpy.data.filepath
    if path and os.path.isfile(path) and (bpy.app.background or not bpy.data.is_dirty):
        return file_fingerprint(path)
    return "unsaved:%d:%f" % (os.getpid(), time.time())


def output_paths(output, objects):
    """{object name: final .pc2 path}. output is a directory, or a .pc2 file path for a single object."""
    output = bpy.path.abspath(output) if output.startswith("//") else output
    output = os.path.abspath(os.path.expanduser(output))
    if output.lower().endswith(".pc2"):
        if len(objects) != 1:
            raise BakeError("%s is a file name, but %d objects are baked: give a directory (one <object>.pc2 each)"
                            % (output, len(objects)))
        return os.path.dirname(output), {objects[0].name: output}
    paths = {}
    for obj in objects:
        path = os.path.join(output, file_name(obj.name))
        if path in paths.values():
            raise BakeError("two objects would be written to the same file %s: rename one of them" % path)
        paths[obj.name] = path
    return output, paths


class Target:
    """One object of a bake: how it is read, where it goes, and the part being written."""

    def __init__(self, obj, final_path, source):
        self.reader = capture.ObjectReader(obj)
        self.name = obj.name
        self.final_path = final_path
        self.identity = {
            "object": obj.name,
            "vertices": self.reader.vertex_count,
            "source": source,
            "blender": bpy.app.version_string,
            "addon": addon_version(),
            "content": "object-space positions leaving Volume Preservation",
        }
        self.writer = None
        self.missing = []


class Bake:
    """A bake of objects over frames into directory. owner=False (a chunk of a bigger bake) never deletes
    anything it did not write."""

    def __init__(self, scene, objects, frames, output, source=None, owner=True, log=None):
        if not frames:
            raise BakeError("the frame range is empty")
        self.scene = scene
        self.frames = sorted(set(frames))
        self.source = source or current_source()
        self.owner = owner
        self.log = log or (lambda message: None)
        self.directory, paths = output_paths(output, objects)
        self.targets = [Target(obj, paths[obj.name], self.source) for obj in objects]
        self.work = []
        self.position = 0
        self.started = None
        self._frame_before = None

    # -- planning --

    def check_output(self):
        try:
            pc2.check_writable_directory(self.directory)
        except pc2.PC2Error as error:
            raise BakeError(str(error)) from None

    def plan(self, restart=False):
        """Finds what is already baked; self.work becomes the frames still to do (for any object)."""
        self.check_output()
        work = set()
        for target in self.targets:
            if restart and self.owner:
                pc2.remove_parts_directory(target.final_path)
                pc2.remove_paths([pc2.sidecar_path(target.final_path)])
            parts, stale = pc2.scan_parts(target.final_path, target.identity)
            if stale and self.owner:
                self.log("%s: removing %d parts of an older bake (another .blend, object or version)"
                         % (target.name, len(stale)))
                pc2.remove_paths(stale)
            target.missing = pc2.missing_frames(self.frames, parts)
            work.update(target.missing)
        self.work = sorted(work)
        self.position = 0
        return self.work

    @property
    def done(self):
        return self.position >= len(self.work)

    @property
    def frames_done(self):
        return self.position

    # -- baking --

    def start(self):
        self._frame_before = (self.scene.frame_current, self.scene.frame_subframe)
        self.started = time.monotonic()
        SESSION.note_baking(True)  # until restore_frame: the frames are corrected with the render settings
        for target in self.targets:
            # A script may have changed weights or the rest mesh without an update since: the first
            # frame baked reads them again.
            SESSION.note_mesh_changed(target.reader.obj, at_once=True)
        depsgraph = bpy.context.evaluated_depsgraph_get()
        capture.check_evaluated([target.reader.obj for target in self.targets], depsgraph)

    def step(self):
        """Bakes the next frame for every object. Raises BakeError or pc2.PC2Error (DiskFullError)."""
        if self.started is None:
            self.start()
        frame = self.work[self.position]
        self.scene.frame_set(frame)
        depsgraph = bpy.context.evaluated_depsgraph_get()
        for target in self.targets:
            positions = target.reader.read(depsgraph, frame)
            if target.writer is not None and target.writer.next_frame != frame:
                target.writer.finish()
                target.writer = None
            if target.writer is None:
                target.writer = pc2.PartWriter(target.final_path, target.identity, target.reader.vertex_count, frame)
            target.writer.append(frame, positions)
        self.position += 1
        return frame

    def finish_parts(self):
        """Completes the parts being written (each becomes a valid PC2 file)."""
        for target in self.targets:
            if target.writer is not None:
                target.writer.finish()
                target.writer = None

    def close(self):
        """Stops: parts being written keep their finished frames. Puts the scene back on its frame."""
        for target in self.targets:
            if target.writer is not None:
                target.writer.close()
                target.writer = None
        self.restore_frame()

    def restore_frame(self):
        SESSION.note_baking(False)
        if self._frame_before is not None:
            frame, subframe = self._frame_before
            self._frame_before = None
            self.scene.frame_set(frame, subframe=subframe)

    # -- merging --

    def merge(self):
        """One PC2 file per object from its parts. Raises pc2.MissingFramesError when frames are missing."""
        first, last = self.frames[0], self.frames[-1]
        if self.frames != list(range(first, last + 1)):
            raise BakeError("a PC2 file holds one range of frames: %s has gaps" % pc2.format_frames(self.frames))
        written = []
        for target in self.targets:
            parts, stale = pc2.scan_parts(target.final_path, target.identity)
            record = {"identity": target.identity, "object": target.name, "blend": bpy.data.filepath}
            pc2.merge(parts, first, last, target.final_path, target.reader.vertex_count, record=record)
            pc2.remove_parts_directory(target.final_path)
            written.append(target.final_path)
        return written


class Progress:
    """Progress lines on stderr: frames done, frames per second, estimated time left (at most one a second)."""

    def __init__(self, total, label="lvp_bake", stream=None, interval=1.0):
        self.total = total
        self.label = label
        self.stream = stream or sys.stderr
        self.interval = interval
        self.started = time.monotonic()
        self.last = time.monotonic()
        self.done = 0
        self.printed = 0

    def text(self, done):
        elapsed = max(time.monotonic() - self.started, 1e-9)
        rate = done / elapsed
        left = (self.total - done) / rate if rate > 0 else float("inf")
        percent = 100.0 * done / self.total if self.total else 100.0
        eta = "ETA %s" % format_seconds(left) if done < self.total else "took %s" % format_seconds(elapsed)
        return "%s: %d/%d frames (%.0f%%), %.2f frames/s, %s" % (self.label, done, self.total, percent, rate, eta)

    def update(self, done, force=False):
        """Prints a line when forced, when the bake completes, and otherwise at most once per interval while
        frames get done (once per 10 intervals while none do, e.g. while --jobs processes start)."""
        now = time.monotonic()
        changed = done != self.printed
        finished = done >= self.total and changed
        due = now - self.last >= (self.interval if changed else 10 * self.interval)
        self.done = done
        if force or finished or due:
            self.last = now
            self.printed = done
            self.stream.write(self.text(done) + "\n")
            self.stream.flush()


def format_seconds(seconds):
    if seconds == float("inf"):
        return "unknown"
    seconds = int(round(seconds))
    return "%d:%02d:%02d" % (seconds // 3600, seconds // 60 % 60, seconds % 60)


def export_alembic(context, objects, first, last, directory, log):
    """<directory>/<name>.abc per object, written atomically, when this Blender has Alembic. Returns paths."""
    if not bpy.app.alembic.supported:
        log("Alembic not written: this Blender was built without Alembic (bpy.app.alembic.supported is False); "
            "the PC2 files are complete")
        return []
    written = []
    view_layer = context.view_layer
    selected = [obj for obj in view_layer.objects if obj.select_get()]
    active = view_layer.objects.active
    try:
        for obj in objects:
            for other in view_layer.objects:
                other.select_set(other == obj)
            view_layer.objects.active = obj
            final = os.path.join(directory, file_name(obj.name)[:-len(".pc2")] + ".abc")
            temporary = pc2.temporary_name(final) + ".abc"
            try:
                result = bpy.ops.wm.alembic_export(filepath=temporary, start=first, end=last, selected=True,
                                                   visible_objects_only=False, export_hair=False,
                                                   export_particles=False)
                if 'FINISHED' not in result or not os.path.isfile(temporary):
                    raise BakeError("the Alembic export of %r failed" % obj.name)
                os.replace(temporary, final)
            finally:
                if os.path.exists(temporary):
                    os.unlink(temporary)
            written.append(final)
    finally:
        for other in view_layer.objects:
            other.select_set(other in selected)
        view_layer.objects.active = active
    return written
