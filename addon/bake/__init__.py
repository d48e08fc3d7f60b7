# SPDX-License-Identifier: GPL-3.0-or-later
"""Baking the corrected animation to PC2 point caches (docs/baking.md):

    pc2.py       the PC2 format, crash-safe part files, merging (pure Python, no bpy)
    capture.py   what is baked for an object at a frame, and the checks before baking
    engine.py    one bake in this Blender: plan, frame after frame, merge; progress; Alembic
    operator.py  object.lvp_bake (modal with progress bar and Esc in the interface)
    command.py   the headless command `blender -b FILE -c lvp_bake ...` (Blender 4.2+), --jobs N
    lvp_bake.py  the same command for any Blender: `blender -b FILE --python .../bake/lvp_bake.py -- ...`

register() / unregister() are called by the add-on's __init__.py.
"""

import bpy

from . import pc2  # noqa: F401
from . import capture  # noqa: F401
from . import engine  # noqa: F401
from . import operator
from . import command


_register_classes, _unregister_classes = bpy.utils.register_classes_factory(operator.classes)


def register():
    _register_classes()
    command.register()


def unregister():
    command.unregister()
    _unregister_classes()
