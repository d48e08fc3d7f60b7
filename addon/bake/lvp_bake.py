# SPDX-License-Identifier: GPL-3.0-or-later
"""The bake command for any Blender (3.4+) through --python, shipped inside the add-on:

    blender -b shot.blend --python <add-on folder>/bake/lvp_bake.py -- --objects Giraffe --frames 1-250 \\
        --output /shared/cache/shot

Same options as `blender -b shot.blend -c lvp_bake ...` on Blender 4.2+ (see command.py, docs/baking.md).
It uses the add-on this file belongs to: the enabled one when it is enabled, else it enables it for this
run only (the user's preferences are not changed). Exits with the command's status.
"""

import os
import sys

import bpy

PACKAGE_DIR = os.path.dirname(os.path.dirname(os.path.realpath(__file__)))


def _loaded_package():
    """The add-on package already imported from PACKAGE_DIR, or None."""
    init = os.path.join(PACKAGE_DIR, "__init__.py")
    for module in list(sys.modules.values()):
        path = getattr(module, "__file__", None)
        if path and os.path.basename(path) == "__init__.py" and os.path.realpath(path) == init:
            return module
    return None


def _module_name():
    """How Blender names the add-on in PACKAGE_DIR: bl_ext.<repository>.<id> for an installed extension
    (Blender 4.2+), else the folder name."""
    parent = os.path.dirname(PACKAGE_DIR)
    name = os.path.basename(PACKAGE_DIR)
    extensions = getattr(bpy.context.preferences, "extensions", None)
    if extensions is not None:
        for repository in extensions.repos:
            directory = getattr(repository, "directory", "")
            if repository.enabled and directory and os.path.realpath(directory) == parent:
                return "bl_ext.%s.%s" % (repository.module, name)
    if parent not in sys.path:
        sys.path.insert(0, parent)
    return name


def enable_addon():
    import addon_utils
    package = _loaded_package()
    if package is None or not hasattr(bpy.types.Object, "lvp"):
        name = package.__name__ if package is not None else _module_name()
        package = addon_utils.enable(name, default_set=False, handle_error=None)
        if package is None or not hasattr(bpy.types.Object, "lvp"):
            raise RuntimeError("could not enable the add-on %s from %s" % (name, PACKAGE_DIR))
        # The .blend was loaded before the add-on was there: do what its load_post handler does.
        package.handlers.load_post()
    return package


def main():
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    try:
        package = enable_addon()
    except Exception as error:
        sys.stderr.write("lvp_bake: error: %s\n" % error)
        return 1
    from importlib import import_module
    command = import_module(package.__name__ + ".bake.command")
    return command.run(argv)


if __name__ == "__main__":
    status = main()
    sys.stdout.flush()
    sys.stderr.flush()
    sys.exit(status)
