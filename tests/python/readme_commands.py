# SPDX-License-Identifier: GPL-3.0-or-later
"""The commands that README.md shows, and who runs each of them, so that README cannot go stale.

A command is a line of a fenced code block tagged sh (continuation backslashes joined), or an inline
code span that starts like a command (`./build.sh ...`, `blender ...`, `cp `, `sudo`, `apt-get`, `python3`,
`tests/blender/run.sh ...`): paths alone are not commands. Every one must
be listed in COMMANDS with what exercises it; tests/python/test_readme.py fails when README gains a
command that is not listed here, or loses one that is. Commands exercised by "readme-blender" are run
as written (placeholders replaced, see PLACEHOLDERS) by tests/blender/test_readme_commands.py.

Used by tests/python/test_readme.py (/usr/bin/python3) and tests/blender/test_readme_commands.py
(inside Blender); plain Python, no Blender.
"""

import os
import re

HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.dirname(os.path.dirname(HERE))
README = os.path.join(REPO, "README.md")

# Who runs each command. Kinds:
#   self          the command is one of the two commands: CI runs `./build.sh test` (.ci/run), and
#                 `./build.sh demo` is the demo itself (its output is checked by test_demo_images.py)
#   readme-python run by tests/python/test_readme.py, output compared with README's tables
#   readme-blender run as written by tests/blender/test_readme_commands.py, in the Blender versions given
#   blender-test  run by another headless-Blender test (the file named), in its own form
COMMANDS = {
    "./build.sh demo": ("self", "build.sh demo -> demo/run.sh; tests/blender/test_demo_images.py checks demo/out"),
    "./build.sh test": ("self", ".ci/run"),
    "./build.sh test-c test_correction": ("readme-python", "tests/python/test_readme.py"),
    "mkdir -p ~/.config/blender/3.4/scripts/addons": ("readme-blender", "3.4"),
    "cp -r dist/local_volume_preservation ~/.config/blender/3.4/scripts/addons/": ("readme-blender", "3.4"),
    "blender --command extension install-file --repo user_default --enable "
    "dist/local_volume_preservation-{version}-linux_x64.zip": ("readme-blender", "4.2+"),
    "blender -b shot.blend -c lvp_bake --objects Character --frames 1-250 --output /path/to/cache --jobs 2":
        ("readme-blender", "4.2+"),
    "blender -b shot.blend --python dist/local_volume_preservation/bake/lvp_bake.py -- --objects Character "
    "--frames 1-250 --output /path/to/cache --jobs 2": ("readme-blender", "any"),
    "blender -b shot.blend -c lvp_bake --objects Character --frames 1-125 --output /path/to/cache --chunk":
        ("readme-blender", "4.2+"),
    "blender -b shot.blend -c lvp_bake --objects Character --frames 126-250 --output /path/to/cache --chunk":
        ("readme-blender", "4.2+"),
    "blender -b shot.blend -c lvp_bake --objects Character --frames 1-250 --output /path/to/cache --merge":
        ("readme-blender", "4.2+"),
    "blender -b … -a": ("blender-test", "tests/blender/test_files.py"),
}

# Placeholders in README's commands, replaced by the tests that run them.
PLACEHOLDERS = ("blender", "shot.blend", "Character", "/path/to/cache", "~")

INLINE_COMMAND = re.compile(r"^(\./\S+|blender\s|cp\s|sudo\s|apt-get\s|apt\s|python3?\s|\S+\.sh\b)")


def version():
    """The add-on's version, from blender_manifest.toml (build.sh names the zip with it)."""
    with open(os.path.join(REPO, "blender_manifest.toml")) as file:
        for line in file:
            match = re.match(r'^version\s*=\s*"([^"]+)"', line)
            if match:
                return match.group(1)
    raise ValueError("no version in blender_manifest.toml")


def known_commands():
    """COMMANDS with {version} filled in: {command: (kind, detail)}."""
    current = version()
    return {command.replace("{version}", current): value for command, value in COMMANDS.items()}


def read_readme(path=README):
    with open(path, encoding="utf-8") as file:
        return file.read()


def extract_commands(text):
    """[(command, line number)] in README order: sh code block lines and inline command spans."""
    commands = []
    in_block = False
    block_is_shell = False
    pending = ""
    pending_line = 0
    for number, line in enumerate(text.splitlines(), 1):
        stripped = line.strip()
        if stripped.startswith("```"):
            if not in_block:
                in_block = True
                block_is_shell = stripped[3:].strip() in ("sh", "bash", "shell", "console")
            else:
                in_block = False
            continue
        if in_block:
            if not block_is_shell or not stripped or stripped.startswith("#"):
                continue
            if stripped.startswith("$ "):
                stripped = stripped[2:]
            if not pending:
                pending_line = number
            if stripped.endswith("\\"):
                pending += stripped[:-1].strip() + " "
                continue
            commands.append(((pending + stripped).strip(), pending_line))
            pending = ""
            continue
        for span in re.findall(r"`([^`]+)`", line):
            if INLINE_COMMAND.match(span):
                commands.append((span.strip(), number))
    return commands


def headings(text, level=2):
    """The README's headings of one level, in order (fenced code skipped)."""
    found = []
    in_block = False
    for line in text.splitlines():
        if line.strip().startswith("```"):
            in_block = not in_block
            continue
        if not in_block and line.startswith("#" * level + " "):
            found.append(line[level + 1:].strip())
    return found


def commands_run_in_blender(text, blender_version):
    """The README commands that tests/blender/test_readme_commands.py runs in this Blender (a tuple
    (major, minor)), in README order."""
    known = known_commands()
    chosen = []
    for command, _line in extract_commands(text):
        kind, which = known.get(command, (None, None))
        if kind != "readme-blender":
            continue
        if which == "any" or (which == "4.2+" and blender_version >= (4, 2)) or \
                (which == "3.4" and blender_version < (4, 2)):
            chosen.append(command)
    return chosen
