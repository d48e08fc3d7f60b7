# SPDX-License-Identifier: GPL-3.0-or-later
"""tests/blender/run.sh and runner.py when a Blender dies in a test: the rest of the suite still runs in a new
Blender, the test is run alone, a crash that does not recur is reported and does not fail the run, one that
recurs does, and what passed or failed before the crash is counted.

The "Blender" here is this Python running runner.py with a stand-in for bpy (run.sh takes any executable as
--blender), and the tests are a module written for each case whose second test kills its interpreter with a
segmentation fault: once (a marker file remembers it) or every time.
"""
import os
import shutil
import subprocess
import sys
import tempfile
import textwrap
import unittest

REPO = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
RUN = os.path.join(REPO, "tests", "blender", "run.sh")

FAKE_BLENDER = """\
#!{python}
# Blender's command line as run.sh gives it: ... --python runner.py -- RUNNER_ARGUMENTS
import runpy, sys
arguments = sys.argv[1:]
script = arguments[arguments.index("--python") + 1]
sys.argv = [script] + arguments[arguments.index("--"):]
runpy.run_path(script, run_name="__main__")
"""

FAKE_BPY = """\
import sys
class app:
    version = (3, 4, 1)
    version_string = "3.4.1 (a stand-in for the runner's tests)"
    binary_path = sys.executable
"""

TESTS = """\
import ctypes, os, unittest
MARKER = os.path.join(os.environ["FAKE_MARKERS"], "crashed")

class TestCrashing(unittest.TestCase):
    def test_1_passes(self):
        pass

    def test_2_crashes(self):
        if os.environ.get("CRASH_EVERY_TIME") or not os.path.exists(MARKER):
            open(MARKER, "w").close()
            ctypes.string_at(0)

    def test_3_after_the_crash(self):
        self.assertFalse(os.environ.get("FAIL_AFTER"), "the test after the crash fails")
"""


class TestDeadBlender(unittest.TestCase):
    def setUp(self):
        self.directory = tempfile.mkdtemp(prefix="lvp-runner-test-")
        self.addCleanup(shutil.rmtree, self.directory, True)
        self.blender = os.path.join(self.directory, "blender")
        with open(self.blender, "w") as f:
            f.write(FAKE_BLENDER.format(python=sys.executable))
        os.chmod(self.blender, 0o755)
        modules = os.path.join(self.directory, "modules")
        os.makedirs(os.path.join(modules, "bpy"))
        with open(os.path.join(modules, "bpy", "__init__.py"), "w") as f:
            f.write(FAKE_BPY)
        with open(os.path.join(modules, "test_fake_crash.py"), "w") as f:
            f.write(TESTS)
        self.markers = os.path.join(self.directory, "markers")
        os.makedirs(self.markers)
        self.environment = dict(os.environ, PYTHONPATH=modules, FAKE_MARKERS=self.markers)

    def run_suite(self, **environment):
        result = subprocess.run([RUN, "--no-build", "--blender", self.blender, "test_fake_crash"],
                                env=dict(self.environment, **environment), cwd=self.directory,
                                stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, timeout=600)
        return result.returncode, result.stdout

    def assertSummary(self, output, passed, failed):
        self.assertIn("blender: %d passed, %d failed, 0 skipped" % (passed, failed), output)

    def test_a_crash_that_does_not_recur(self):
        status, output = self.run_suite()
        self.assertEqual(status, 0, output)
        self.assertIn("died (status", output)
        self.assertIn("going on after test_fake_crash.TestCrashing.test_2_crashes", output)
        self.assertIn("crashed in test_fake_crash.TestCrashing.test_2_crashes", output)
        self.assertIn("in test_2_crashes", output, "the crashed thread's Python stack")
        self.assertIn("WARNING", output)
        self.assertSummary(output, 3, 0)
        self.assertFalse([name for name in os.listdir(self.directory) if name.startswith("core")], "core files left")

    def test_a_failure_before_or_after_a_crash_still_fails(self):
        status, output = self.run_suite(FAIL_AFTER="1")
        self.assertEqual(status, 1, output)
        self.assertIn("test_fake_crash.TestCrashing.test_3_after_the_crash", output.split("FAILED")[-1])
        self.assertSummary(output, 2, 1)

    def test_a_crash_that_recurs_fails(self):
        status, output = self.run_suite(CRASH_EVERY_TIME="1")
        self.assertEqual(status, 1, output)
        self.assertIn("test_fake_crash.TestCrashing.test_2_crashes    # Blender", output.split("FAILED")[-1])
        self.assertIn("and again alone", output)
        self.assertSummary(output, 2, 1)


if __name__ == "__main__":
    unittest.main()
