# SPDX-License-Identifier: GPL-3.0-or-later
"""object.lvp_bake: bakes the volume-corrected animation of the selected objects to PC2 point caches.

From the interface (invoke) it runs modal: one frame at a time between events, with a progress bar
(window_manager.progress_*) and Esc to cancel, which keeps the frames already written so that the next
bake of the same saved file resumes. From scripts and background Blender (execute) it runs to the end
before returning. What is baked and where it goes: capture.py and docs/baking.md.
"""

import os
import time

import bpy
from bpy.props import BoolProperty, IntProperty, StringProperty

from . import capture
from . import engine
from . import pc2
from .capture import BakeError

# How long one timer event of the modal bake may work before the interface gets a turn.
SLICE_SECONDS = 0.1


def _selected_objects(context):
    """The selected objects to bake; an armature selected along with its meshes is skipped."""
    objects = list(context.selected_objects) or ([context.active_object] if context.active_object else [])
    rigs = {modifier.object.name_full for obj in objects if obj.type == 'MESH' for modifier in obj.modifiers
            if modifier.type == 'ARMATURE' and modifier.object is not None}
    return [obj for obj in objects if not (obj.type == 'ARMATURE' and obj.name_full in rigs)]


class OBJECT_OT_lvp_bake(bpy.types.Operator):
    """Bake the volume-corrected animation of the selected objects to PC2 point caches (object space, one \
<object>.pc2 each), for a Mesh Cache modifier, Maya, 3ds Max or Houdini. Esc cancels and keeps the frames \
already baked"""

    bl_idname = "object.lvp_bake"
    bl_label = "Bake Volume Preservation to PC2"
    bl_options = {'REGISTER'}

    filepath: StringProperty(
        name="Output", subtype='FILE_PATH', default="//lvp_cache/",
        description="Directory for the <object>.pc2 files, or a .pc2 file name when one object is baked "
                    "(// is relative to the .blend file)")
    frame_start: IntProperty(name="Start", description="First frame to bake (default: the scene's start)")
    frame_end: IntProperty(name="End", description="Last frame to bake (default: the scene's end)")
    resume: BoolProperty(
        name="Resume", default=True,
        description="Keep frames baked before from the same saved file and bake only the missing ones")
    alembic: BoolProperty(
        name="Alembic", default=False,
        description="Also write <object>.abc with Blender's Alembic exporter (when this Blender has Alembic)")

    @classmethod
    def poll(cls, context):
        return context.mode == 'OBJECT' and bool(_selected_objects(context))

    # -- shared by execute and invoke --

    def _prepare(self, context):
        scene = context.scene
        if not self.properties.is_property_set("frame_start"):
            self.frame_start = scene.frame_start
        if not self.properties.is_property_set("frame_end"):
            self.frame_end = scene.frame_end
        if self.frame_end < self.frame_start:
            raise BakeError("the frame range %d-%d is reversed: the end frame must not come before the start frame"
                            % (self.frame_start, self.frame_end))
        if not self.filepath:
            raise BakeError("no output: set filepath to a directory (or a .pc2 file for one object)")
        if self.filepath.startswith("//") and not bpy.data.filepath:
            raise BakeError("the output %s is relative to the .blend file, which is not saved: save it first or "
                            "give an absolute path" % self.filepath)
        objects = _selected_objects(context)
        problems = [problem for problem in (capture.object_problem(scene, obj) for obj in objects) if problem]
        if problems:
            raise BakeError("; ".join(problems))
        bake = engine.Bake(scene, objects, range(self.frame_start, self.frame_end + 1), self.filepath)
        bake.log = lambda message: self.report({'INFO'}, message)
        bake.plan(restart=not self.resume)
        return bake

    def _complete(self, context, bake):
        bake.finish_parts()
        bake.restore_frame()
        written = bake.merge()
        if self.alembic:
            written += engine.export_alembic(context, [target.reader.obj for target in bake.targets],
                                             self.frame_start, self.frame_end, bake.directory,
                                             lambda message: self.report({'WARNING'}, message))
        self.report({'INFO'}, "Baked frames %d-%d: %s" % (self.frame_start, self.frame_end,
                                                         ", ".join(os.path.basename(path) for path in written)))

    def _fail(self, bake, error):
        if bake is not None:
            bake.close()
        message = str(error)
        if isinstance(error, pc2.DiskFullError):
            message += ": free some space and bake again, the frames already baked are kept"
        elif isinstance(error, pc2.MissingFramesError):
            message += ": bake again to finish them"
        self.report({'ERROR'}, message)
        return {'CANCELLED'}

    # -- scripts and background: to the end --

    def execute(self, context):
        bake = None
        try:
            bake = self._prepare(context)
            while not bake.done:
                bake.step()
            self._complete(context, bake)
        except (BakeError, pc2.PC2Error) as error:
            return self._fail(bake, error)
        finally:
            if bake is not None:
                bake.close()
        return {'FINISHED'}

    # -- interface: modal, progress bar, Esc --

    def invoke(self, context, event):
        if context.window is None or bpy.app.background:
            return self.execute(context)
        try:
            self._bake = self._prepare(context)
        except (BakeError, pc2.PC2Error) as error:
            return self._fail(None, error)
        window_manager = context.window_manager
        window_manager.progress_begin(0, max(1, len(self._bake.work)))
        self._timer = window_manager.event_timer_add(0.001, window=context.window)
        window_manager.modal_handler_add(self)
        if context.workspace is not None:
            context.workspace.status_text_set("Baking Volume Preservation to PC2: Esc to cancel (baked frames "
                                              "are kept)")
        return {'RUNNING_MODAL'}

    def _end_modal(self, context):
        window_manager = context.window_manager
        window_manager.event_timer_remove(self._timer)
        window_manager.progress_end()
        if context.workspace is not None:
            context.workspace.status_text_set(None)

    def modal(self, context, event):
        bake = self._bake
        if event.type == 'ESC':
            kept = bake.frames_done
            bake.close()
            self._end_modal(context)
            self.report({'WARNING'}, "Bake cancelled: %d of %d frames baked are kept in %s; bake again (same saved "
                                     "file) to finish" % (kept, len(bake.work), bake.directory))
            return {'CANCELLED'}
        if event.type != 'TIMER':
            return {'RUNNING_MODAL'}
        try:
            deadline = time.monotonic() + SLICE_SECONDS
            while not bake.done and time.monotonic() < deadline:
                bake.step()
            context.window_manager.progress_update(bake.frames_done)
            if bake.done:
                self._complete(context, bake)
                bake.close()
                self._end_modal(context)
                return {'FINISHED'}
        except (BakeError, pc2.PC2Error) as error:
            self._end_modal(context)
            return self._fail(bake, error)
        return {'RUNNING_MODAL'}


classes = (OBJECT_OT_lvp_bake,)
