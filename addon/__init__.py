# SPDX-License-Identifier: GPL-3.0-or-later
"""Local Volume Preservation: keeps skinned meshes from losing volume at bending joints.

Implements D. Rohmer, S. Hahmann, M.-P. Cani, "Local volume preservation for skinned characters"
(Computer Graphics Forum 27(7), 2008) as a live modifier right after the Armature modifier. The
geometry is done by the compiled C core (_lvp); this package is the Blender glue.

The same folder is a Blender 3.4+ add-on (bl_info) and, with blender_manifest.toml beside this
file, a Blender 4.2+ extension. This file only delegates registration.
"""

bl_info = {
    "name": "Local Volume Preservation",
    "author": "Local Volume Preservation developers",
    "version": (0, 1, 0),
    "blender": (3, 4, 0),
    "location": "Properties > Modifiers > Volume Preservation",
    "description": "Keeps skinned characters from losing volume at bending joints (Rohmer et al. 2008)",
    "doc_url": "",
    "category": "Animation",
}

if "bpy" in locals():
    import importlib
    for _module in (names, mesh_data, node_group, changes, session, bound_object, bindings,  # noqa: F821
                    live, display, properties, operators, ui, handlers):  # noqa: F821
        importlib.reload(_module)
    del _module

import bpy  # noqa: E402,F401

from . import names  # noqa: E402
from . import mesh_data  # noqa: E402
from . import node_group  # noqa: E402
from . import changes  # noqa: E402,F401
from . import session  # noqa: E402
from . import bound_object  # noqa: E402,F401
from . import bindings  # noqa: E402
from . import live  # noqa: E402
from . import display  # noqa: E402
from . import properties  # noqa: E402
from . import operators  # noqa: E402
from . import ui  # noqa: E402
from . import handlers  # noqa: E402
from . import bake  # noqa: E402  (baking to point caches: bake/__init__.py)

# Registered in this order, unregistered in reverse.
modules = (
    properties,
    operators,
    ui,
    handlers,
    bake,
)


def register():
    for module in modules:
        module.register()


def unregister():
    for module in reversed(modules):
        module.unregister()
    session.SESSION.close_bindings()
