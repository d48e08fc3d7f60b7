# SPDX-License-Identifier: GPL-3.0-or-later
"""README.md cannot go stale: its sections come in their agreed order (SECTIONS), every command it shows is one
that the build or a test runs (readme_commands.COMMANDS; an unknown command fails), its paths, names,
parameters and pictures exist, and its measured tables are what the code measures.

Run by `./build.sh test` with /usr/bin/python3 (no Blender):

    PYTHONPATH=build /usr/bin/python3 -m unittest discover -s tests/python -t tests/python -k test_readme
"""

import ast
import os
import re
import subprocess
import unittest

import readme_commands

REPO = readme_commands.REPO
SECTIONS = [
    "What it does for an animator",
    "The two commands",
    "Installing it in Blender",
    "Using it, step by step",
    "Baking headless",
    "Parameters",
    "Measured",
    "What it does not do yet",
]


def read(*parts):
    with open(os.path.join(REPO, *parts), encoding="utf-8") as file:
        return file.read()


def number(text):
    """A float from README or test output: '-0.170 %', '+1.237%', '−0.0000 %'."""
    return float(text.replace("\u2212", "-").replace("%", "").strip())


def settings_properties():
    """{property: its UI name} of Object.lvp (LVP_PG_settings in addon/properties.py), hidden ones left out."""
    tree = ast.parse(read("addon", "properties.py"))
    properties = {}
    for node in ast.walk(tree):
        if isinstance(node, ast.ClassDef) and node.name == "LVP_PG_settings":
            for statement in node.body:
                if not (isinstance(statement, ast.AnnAssign) and isinstance(statement.annotation, ast.Call)):
                    continue
                keywords = {keyword.arg: keyword.value for keyword in statement.annotation.keywords}
                options = keywords.get("options")
                if options is not None and "HIDDEN" in ast.unparse(options):
                    continue
                name = keywords.get("name")
                properties[statement.target.id] = ast.literal_eval(name) if name is not None else None
    return properties


def effect_names():
    tree = ast.parse(read("addon", "properties.py"))
    for node in tree.body:
        if isinstance(node, ast.Assign) and any(getattr(target, "id", "") == "EFFECT_ITEMS" for target in node.targets):
            return [item[1] for item in ast.literal_eval(node.value)]
    raise AssertionError("EFFECT_ITEMS not found in addon/properties.py")


def operator_labels():
    """{bl_idname: bl_label} of the add-on's operators."""
    labels = {}
    for relative in (("addon", "operators.py"), ("addon", "bake", "operator.py")):
        path = os.path.join(REPO, *relative)
        if not os.path.isfile(path):
            continue
        for node in ast.walk(ast.parse(read(*relative))):
            if isinstance(node, ast.ClassDef):
                values = {}
                for statement in node.body:
                    if isinstance(statement, ast.Assign) and isinstance(statement.value, ast.Constant):
                        for target in statement.targets:
                            if isinstance(target, ast.Name):
                                values[target.id] = statement.value.value
                if "bl_idname" in values:
                    labels[values["bl_idname"]] = values.get("bl_label")
    return labels


class TestReadmeCommands(unittest.TestCase):

    def setUp(self):
        self.text = readme_commands.read_readme()
        self.commands = readme_commands.extract_commands(self.text)
        self.known = readme_commands.known_commands()

    def test_every_command_is_exercised(self):
        unknown = ["line %d: %s" % (line, command) for command, line in self.commands if command not in self.known]
        self.assertEqual(unknown, [], "README.md shows commands that no test or build step runs. Make a test run "
                                      "each one and list it in tests/python/readme_commands.py COMMANDS:\n"
                                      + "\n".join(unknown))

    def test_every_listed_command_is_in_readme(self):
        shown = {command for command, _line in self.commands}
        missing = [command for command in self.known if command not in shown]
        self.assertEqual(missing, [], "tests/python/readme_commands.py lists commands README.md no longer shows "
                                      "(remove them there, or put them back in README):\n" + "\n".join(missing))

    def test_the_two_commands_come_first(self):
        section = self.text.split("## The two commands", 1)[1].split("\n## ", 1)[0]
        block = re.search(r"```sh\n(.*?)```", section, re.S)
        self.assertIsNotNone(block, "no code block in 'The two commands'")
        self.assertEqual(block.group(1).split(), ["./build.sh", "demo", "./build.sh", "test"])

    def test_build_sh_handles_them(self):
        build = read("build.sh")
        for case in ("demo", "test", "test-c"):
            self.assertTrue(re.search(r"(?m)^\t%s\)" % re.escape(case), build), "build.sh has no '%s' command" % case)
        self.assertIn('"$ROOT/demo/run.sh"', build, "./build.sh demo should run demo/run.sh")
        self.assertTrue(os.access(os.path.join(REPO, "demo", "run.sh"), os.X_OK), "demo/run.sh is not executable")
        self.assertRegex(read(".ci", "run"), r"(?m)^\./build\.sh test$", ".ci/run should run ./build.sh test")

    def test_commands_run_by_other_tests_are_there(self):
        for command, (kind, where) in self.known.items():
            if kind == "blender-test":
                self.assertTrue(os.path.isfile(os.path.join(REPO, where)), "%s: %s does not exist" % (command, where))
            elif kind == "readme-blender":
                self.assertTrue(os.path.isfile(os.path.join(REPO, "tests", "blender", "test_readme_commands.py")))
        self.assertIn('["-a"]', read("tests", "blender", "test_files.py"),
                      "tests/blender/test_files.py no longer renders with -a (README: blender -b ... -a)")

    def test_bake_script_exists(self):
        self.assertTrue(os.path.isfile(os.path.join(REPO, "addon", "bake", "lvp_bake.py")),
                        "README's 3.4 bake command runs <add-on>/bake/lvp_bake.py")
        self.assertIn('COMMAND = "lvp_bake"', read("addon", "bake", "command.py"))


class TestReadmeContent(unittest.TestCase):

    def setUp(self):
        self.text = readme_commands.read_readme()

    def test_sections_in_their_order(self):
        self.assertEqual(readme_commands.headings(self.text), SECTIONS)

    def test_images_exist_and_are_png(self):
        images = re.findall(r"!\[[^\]]*\]\(([^)]+)\)", self.text)
        self.assertGreaterEqual(len(images), 3, "README should show the demo's pictures")
        self.assertIn("docs/images/cylinder_90.png", images)
        for image in images:
            path = os.path.join(REPO, image)
            self.assertTrue(os.path.isfile(path), "README shows %s, which does not exist" % image)
            with open(path, "rb") as file:
                self.assertEqual(file.read(8), b"\x89PNG\r\n\x1a\n", "%s is not a PNG" % image)
            self.assertLess(os.path.getsize(path), 400 * 1024, "%s is large for a repository" % image)

    def test_relative_links_and_paths_exist(self):
        for target in re.findall(r"\]\(([^)]+)\)", self.text):
            if not re.match(r"^[a-z]+:", target):
                self.assertTrue(os.path.exists(os.path.join(REPO, target.split("#")[0])), "dead link %s" % target)
        outputs = [line.strip().rstrip("/") for line in read(".gitignore").splitlines() if line.strip()]
        for path in re.findall(r"`((?:docs|tests|csrc|addon|demo)/[^`\s]*)`", self.text):
            if "/" + path.rstrip("/") in outputs:
                # An output folder (demo/out/): not in a fresh clone, so the command that writes it must name it.
                writers = read("build.sh") + read("demo/run.sh")
                self.assertIn(path, writers, "README names the output %s, which no command writes" % path)
                continue
            self.assertTrue(os.path.exists(os.path.join(REPO, path)), "README names %s, which does not exist" % path)

    def test_package_paths_match_build_sh(self):
        build = read("build.sh")
        platforms_sh = read("platforms.sh")
        self.assertIn('ADDON_ID="local_volume_preservation"', build)
        self.assertIn('"$DIST/$ADDON_ID-$VERSION-$1.zip"', platforms_sh)
        self.assertIn('local folder="$DIST/$ADDON_ID"', platforms_sh)
        platforms = re.search(r"^PLATFORMS=\(([^)]*)\)", platforms_sh, re.M).group(1).split()
        self.assertEqual(sorted(platforms), ["linux_arm64", "linux_x64", "macos_arm64", "macos_x64", "windows_x64"])
        version = readme_commands.version()
        self.assertIn("`dist/local_volume_preservation/`", self.text)
        install = self.text.split("## Installing it in Blender", 1)[1].split("\n## ", 1)[0]
        for platform in platforms:
            self.assertIn("`dist/local_volume_preservation-%s-%s.zip`" % (version, platform), install,
                          "README's install section does not say which zip is for %s" % platform)
        names = re.findall(r"local_volume_preservation-([^ `/]*)\.zip", self.text)
        self.assertTrue(names)
        for name in names:
            self.assertIn(name, ["%s-%s" % (version, platform) for platform in platforms],
                          "every zip name in README should be one that build.sh writes: the version of "
                          "blender_manifest.toml and a platform of platforms.sh")

    def test_every_setting_is_documented(self):
        properties = settings_properties()
        self.assertIn("effect", properties)
        parameters = self.text.split("## Parameters", 1)[1].split("\n## ", 1)[0]
        for prop, ui_name in properties.items():
            if prop.startswith("active_"):
                continue  # the selected row of the restrictions list
            self.assertIn("`%s`" % prop, parameters, "Object.lvp.%s is not in README's Parameters" % prop)
            self.assertIn("| %s |" % ui_name, parameters, "the UI name %r of %s is not in README" % (ui_name, prop))
        for documented in re.findall(r"^\| [^|]+ \| `(\w+)` \|", parameters, re.M):
            self.assertIn(documented, properties, "README documents Object.lvp.%s, which does not exist" % documented)
        for effect in effect_names():
            self.assertIn("**%s**" % effect, parameters, "the effect %s is not explained" % effect)

    def test_ui_names_match_the_add_on(self):
        labels = operator_labels()
        ui = read("addon", "ui.py")
        self.assertIn('bl_label = "Volume Preservation"', ui)
        self.assertIn('bl_context = "modifier"', ui)
        steps = self.text.split("## Using it, step by step", 1)[1].split("\n## ", 1)[0]
        self.assertIn("**Modifiers**", steps)
        for idname in ("object.lvp_add", "object.lvp_bind", "object.lvp_auto_weights"):
            self.assertIn("**%s**" % labels[idname], steps,
                          "the button %s (%s) is not in the steps" % (labels[idname], idname))
        self.assertIn('text="Remove"', ui)
        self.assertIn("**Remove**", steps)
        for idname in re.findall(r"`bpy\.ops\.object\.(\w+)\(\)`", self.text) + \
                re.findall(r"`(lvp_\w+)\(\)`", self.text):
            self.assertIn("object." + idname, labels, "README names an operator object.%s that does not exist" % idname)

    def test_operator_ids_are_named(self):
        for idname in ("lvp_add", "lvp_bind", "lvp_remove", "lvp_auto_weights", "lvp_bake"):
            self.assertIn(idname, self.text)


class TestMeasuredTables(unittest.TestCase):
    """README's tables are what the code measures."""

    def setUp(self):
        self.text = readme_commands.read_readme()

    def test_cylinder_table_is_what_test_correction_prints(self):
        command = "./build.sh test-c test_correction"
        self.assertIn(command, [found for found, _line in readme_commands.extract_commands(self.text)])
        result = subprocess.run(["bash", "-c", command], cwd=REPO, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                                universal_newlines=True, timeout=900)
        self.assertEqual(result.returncode, 0, result.stdout[-3000:])
        printed = {}
        for match in re.finditer(r"^\s+(\d+)\s+\|\s+(\S+)\s+\|\s+(\S+)\s+\|\s+(\S+)\s+\|\s+(\S+)\s+\((\d+)\)",
                                 result.stdout, re.M):
            printed[int(match.group(1))] = (number(match.group(2)), number(match.group(4)), number(match.group(5)),
                                            int(match.group(6)))
        self.assertEqual(sorted(printed), [10, 50, 90], result.stdout[-3000:])
        shown = {}
        for match in re.finditer(r"^\| (\d+)° \| [^|]+ \| ([^|]+) \| [^|]+ \| ([^|]+) \| ([^|(]+) \((\d+)\) \|$",
                                 self.text, re.M):
            shown[int(match.group(1))] = (number(match.group(2)), number(match.group(3)), number(match.group(4)),
                                          int(match.group(5)))
        self.assertEqual(sorted(shown), [10, 50, 90], "README's cylinder table against the paper's Table 2 not found")
        for angle in (10, 50, 90):
            self.assertEqual(shown[angle], printed[angle],
                             "README's row for %d degrees (plain, one pass, iterated, passes) differs from what "
                             "`%s` prints: update README.md" % (angle, command))

    def test_demo_tables_are_quoted(self):
        path = os.path.join(REPO, "demo", "out", "volume_tables.md")
        if not os.path.isfile(path):
            self.skipTest("demo/out/volume_tables.md does not exist: run ./build.sh demo first")
        with open(path, encoding="utf-8") as file:
            lines = [line for line in file.read().splitlines() if line.startswith("|")]
        self.assertTrue(lines)
        missing = [line for line in lines if line not in self.text.splitlines()]
        self.assertEqual(missing, [], "README.md does not quote these lines of the demo's tables (%s):\n%s"
                         % (path, "\n".join(missing)))


if __name__ == "__main__":
    unittest.main()
