"""Headless-Blender unittest runner for tests/blender/test_*.py.

Run by tests/blender/run.sh, once per Blender:

    blender -b --factory-startup -noaudio --python-exit-code 1 \
        --python tests/blender/runner.py -- [options] [TEST_NAME ...]

TEST_NAME is a unittest name: test_module, test_module.TestClass or
test_module.TestClass.test_method. Options:

    --addon-dir DIR       the built add-on folder (default: dist/local_volume_preservation)
    --extension-zip ZIP   the built extension zip (default: the newest dist/local_volume_preservation-*-linux_x64.zip)
    --addon-on-path MODE  put the add-on folder's parent on sys.path so that
                          `import local_volume_preservation` works: auto (default: only on
                          Blender < 4.2, where the folder is how the add-on is installed; on
                          4.2+ the tests install the zip as an extension), yes or no
    --expect-version X.Y  the Blender version run.sh meant to start (test_environment checks it)
    --rerun PREFIX        command that reruns a test when followed by its name
                          (default: "tests/blender/run.sh --blender X.Y")
    --results FILE        write "running ID" while a test runs or is set up (with the tally so far), then a
                          summary line
    --after ID            skip the tests up to ID and ID itself (run.sh goes on this way after a Blender died
                          in ID)
    -k PATTERN            only tests whose name matches (as `python -m unittest -k`)
    -f, --failfast        stop at the first failure
    -q, --quiet           one character per test instead of one line
    --list                print the test ids and exit

What the tests can rely on (also in os.environ, so that a Blender they start sees it too):

    LVP_REPO              absolute path of the repository
    LVP_ADDON_DIR         the add-on folder (may not exist yet: skip with a message)
    LVP_EXTENSION_ZIP     the extension zip ("" when there is none)
    LVP_EXPECT_BLENDER_VERSION   "3.4", "4.3", "5.2" or "" (any Blender)
    LVP_TEST_TMP          a fresh directory under /tmp for this run, removed afterwards
                          (kept with LVP_KEEP_TMP=1); visible at the same path in the chroot
    LVP_RERUN_PREFIX      the --rerun prefix
    tests/blender is on sys.path, so test modules can import helper modules next to them.

Every failing test is reported with the exact command that reruns it alone, and Blender
exits with status 1 when anything failed.
"""

import argparse
import faulthandler
import glob
import os
import shutil
import sys
import tempfile
import time
import unittest

HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.dirname(os.path.dirname(HERE))
ADDON_ID = "local_volume_preservation"


def blender_argv():
    argv = sys.argv
    return argv[argv.index("--") + 1:] if "--" in argv else []


def parse_args(argv):
    parser = argparse.ArgumentParser(prog="runner.py", add_help=True)
    parser.add_argument("--addon-dir", default=os.environ.get("LVP_ADDON_DIR") or
                        os.path.join(REPO, "dist", ADDON_ID))
    parser.add_argument("--extension-zip", default=os.environ.get("LVP_EXTENSION_ZIP"))
    parser.add_argument("--addon-on-path", choices=("auto", "yes", "no"), default="auto")
    parser.add_argument("--expect-version", default=os.environ.get("LVP_EXPECT_BLENDER_VERSION", ""))
    parser.add_argument("--rerun", default=None)
    parser.add_argument("--results", default=None)
    parser.add_argument("--after", default=None)
    parser.add_argument("-k", dest="patterns", action="append", default=[])
    parser.add_argument("-f", "--failfast", action="store_true")
    parser.add_argument("-q", "--quiet", action="store_true")
    parser.add_argument("--list", action="store_true")
    parser.add_argument("names", nargs="*")
    return parser.parse_args(argv)


def newest_zip():
    """This machine's extension zip (Linux x86-64: the one whose module loads here), the newest."""
    zips = glob.glob(os.path.join(REPO, "dist", ADDON_ID + "-*-linux_x64.zip"))
    return max(zips, key=os.path.getmtime) if zips else ""


def iter_tests(suite):
    for item in suite:
        if isinstance(item, unittest.TestSuite):
            yield from iter_tests(item)
        else:
            yield item


def rerun_name(test):
    """The name that makes run.sh run this test alone (also for import and class-fixture errors)."""
    test_id = test.id()
    if getattr(test, "lvp_name", None):
        return test.lvp_name
    if type(test).__name__ == "_FailedTest":
        # A module that failed to import, or a name that does not exist: its name is the method.
        return getattr(test, "_testMethodName", test_id)
    if type(test).__name__ == "_ErrorHolder":
        # setUpClass / setUpModule errors: "setUpClass (test_x.TestY)" -> "test_x.TestY".
        desc = test.description
        if "(" in desc and desc.endswith(")"):
            return desc[desc.index("(") + 1:-1]
        return desc
    return test_id


class LoadError(unittest.TestCase):
    """Stands for a test name that could not be loaded, so that it fails like a test."""

    def __init__(self, name, error):
        super().__init__("test_load")
        self.name, self.error = name, error

    def id(self):
        return self.name

    def __str__(self):
        return "%s (could not be loaded)" % self.name

    def test_load(self):
        raise self.error


def write_running(path, name, passed, failing, skipped):
    """The results file while tests run: the test running (or being set up), then the tally so far, so that
    what ran before a crash is counted."""
    with open(path, "w") as f:
        f.write("running %s\n" % name)
        f.write("so far passed=%d failed=%d skipped=%d\n" % (passed, len(failing), skipped))
        for failed in failing:
            f.write("failed %s\n" % failed)


class Result(unittest.TextTestResult):
    results_file = None
    next_names = {}  # each test's name -> the next test's, whose set-up runs before its startTest

    def failing_names(self):
        names = []
        for test, _ in self.errors + self.failures + [(t, "") for t in self.unexpectedSuccesses]:
            if rerun_name(test) not in names:
                names.append(rerun_name(test))
        return names

    def write_running(self, name):
        if self.results_file:
            write_running(self.results_file, name, getattr(self, "passed", 0), self.failing_names(),
                          len(self.skipped))

    def seconds(self, by):
        """Seconds spent per test module (by="module") or per test (by="test"), set-up included: where the
        run's time budget goes."""
        return self.__dict__.get("_seconds_by_" + by, {})

    def _charge_time(self, test):
        # Everything since the last test ended (a class's or a module's set-up) goes to the test that starts.
        now = time.monotonic()
        spent = now - getattr(self, "_last_mark", now)
        for by, key in (("module", type(test).__module__), ("test", rerun_name(test))):
            seconds = self.__dict__.setdefault("_seconds_by_" + by, {})
            seconds[key] = seconds.get(key, 0.0) + spent
        self._last_mark = now

    def startTest(self, test):
        self._charge_time(test)
        lvp_helpers = sys.modules.get("lvp_helpers")
        if lvp_helpers is not None:
            del lvp_helpers.VOLUME_DISAGREEMENTS[:]
        self.write_running(rerun_name(test))
        self._started = time.monotonic()
        super().startTest(test)
        self.stream.flush()

    def addSuccess(self, test):
        # The core's volumes against the measured ones, on every frame the test corrected (lvp_helpers).
        lvp_helpers = sys.modules.get("lvp_helpers")
        disagreements = list(lvp_helpers.VOLUME_DISAGREEMENTS) if lvp_helpers is not None else []
        if disagreements:
            error = AssertionError("%d corrected frames where the core's volume is not the measured one, first: %s"
                                   % (len(disagreements), "; ".join(disagreements[:3])))
            self.addFailure(test, (AssertionError, error, None))
            return
        super().addSuccess(test)
        self.passed = getattr(self, "passed", 0) + 1

    def stopTest(self, test):
        self._charge_time(test)
        # What runs from here to the next test's start (this class's tear-down, the next one's set-up) is
        # charged to the next test: a Blender that dies there died in it.
        following = self.next_names.get(rerun_name(test))
        if following:
            self.write_running(following)
        super().stopTest(test)
        self.stream.flush()
        sys.stdout.flush()


def main():
    args = parse_args(blender_argv())
    sys.dont_write_bytecode = True  # no __pycache__ in tests/blender
    # On a crash, every thread's Python stack: beside the results, where run.sh finds it and prints it with the
    # failing test at the end of its output (the one part of a long CI log sure to be read).
    fault_file = open(args.results + ".fault", "w") if args.results else sys.stderr
    faulthandler.enable(file=fault_file, all_threads=True)

    import bpy  # noqa: E402  (only inside Blender)

    version = "%d.%d" % tuple(bpy.app.version[:2])
    addon_dir = os.path.abspath(args.addon_dir)
    extension_zip = os.path.abspath(args.extension_zip) if args.extension_zip else newest_zip()
    rerun = args.rerun or "tests/blender/run.sh --blender %s" % version
    # Under run.sh's per-run directory when there is one, so that it goes even after a crash.
    parent = os.environ.get("LVP_RUN_TMP")
    if not (parent and os.path.isdir(parent)):
        parent = "/tmp" if os.path.isdir("/tmp") else None
    tmp = tempfile.mkdtemp(prefix="lvp-test-", dir=parent)

    os.environ.update({
        "LVP_REPO": REPO,
        "LVP_ADDON_DIR": addon_dir,
        "LVP_EXTENSION_ZIP": extension_zip or "",
        "LVP_EXPECT_BLENDER_VERSION": args.expect_version or "",
        "LVP_TEST_TMP": tmp,
        "LVP_RERUN_PREFIX": rerun,
    })
    if HERE not in sys.path:
        sys.path.insert(0, HERE)
    on_path = args.addon_on_path == "yes" or (args.addon_on_path == "auto" and bpy.app.version < (4, 2, 0))
    if on_path:
        parent = os.path.dirname(addon_dir)
        if parent not in sys.path:
            sys.path.insert(1, parent)

    print("[runner] Blender %s (%s), Python %s" % (bpy.app.version_string, bpy.app.binary_path,
                                                   sys.version.split()[0]))
    print("[runner] add-on folder: %s%s" % (addon_dir, "" if os.path.isdir(addon_dir) else " (missing)"))
    print("[runner] extension zip: %s" % (extension_zip or "(none)"))
    sys.stdout.flush()

    loader = unittest.TestLoader()
    if args.patterns:
        loader.testNamePatterns = ["*%s*" % p if "*" not in p else p for p in args.patterns]
    if args.names:
        suite = unittest.TestSuite()
        for name in args.names:
            try:
                loaded = loader.loadTestsFromName(name)
                for test in iter_tests(loaded):
                    if type(test).__name__ == "_FailedTest":
                        test.lvp_name = name  # a name that does not exist: rerun it as given
                suite.addTests(loaded)
            except Exception as error:  # e.g. a SyntaxError in the module: report it as a test
                suite.addTest(LoadError(name, error))
    else:
        suite = loader.discover(start_dir=HERE, pattern="test_*.py", top_level_dir=HERE)

    # One flat suite in the order the tests run (unittest still sets up each class and module once, as the
    # tests move into it), from which --after cuts the tests already run.
    tests = list(iter_tests(suite))
    order = [rerun_name(test) for test in tests]
    if args.after:
        if args.after not in order:
            print("[runner] --after %s: no such test in this run" % args.after)
            return 1
        tests = tests[order.index(args.after) + 1:]
        order = order[order.index(args.after) + 1:]
    suite = unittest.TestSuite(tests)
    Result.next_names = dict(zip(order, order[1:]))

    if args.list:
        for test in tests:
            print(rerun_name(test))
        sys.stdout.flush()
        shutil.rmtree(tmp, ignore_errors=True)
        return 0

    Result.results_file = args.results
    if tests and args.results:
        write_running(args.results, order[0], 0, [], 0)
    runner = unittest.TextTestRunner(stream=sys.stdout, verbosity=1 if args.quiet else 2,
                                     failfast=args.failfast, resultclass=Result)
    start = time.monotonic()
    Result._last_mark = start
    result = runner.run(suite)
    elapsed = time.monotonic() - start
    for by, count in (("module", 12), ("test", 12)):
        slowest = sorted(result.seconds(by).items(), key=lambda item: -item[1])[:count]
        if slowest and not args.list:
            print("[runner] slowest %ss: %s" % (by, ", ".join("%s %.0f s" % item for item in slowest)))

    if os.environ.get("LVP_KEEP_TMP") == "1":
        print("[runner] kept %s" % tmp)
    else:
        shutil.rmtree(tmp, ignore_errors=True)

    failing = result.failing_names()
    failed = len(failing)
    skipped = len(result.skipped)
    passed = getattr(result, "passed", 0)

    if failing:
        print("\n[runner] FAILED on Blender %s; rerun one test alone with:" % bpy.app.version_string)
        for name in failing:
            print("    %s %s" % (rerun, name))
    if result.testsRun == 0 and not failing:
        print("[runner] no test ran")
    summary = "passed=%d failed=%d skipped=%d seconds=%.1f" % (passed, failed, skipped, elapsed)
    print("[runner] Blender %s: %d passed, %d failed, %d skipped in %.1f s"
          % (bpy.app.version_string, passed, failed, skipped, elapsed))
    sys.stdout.flush()
    if args.results:
        with open(args.results, "w") as f:
            f.write("done %s\n" % summary)
            for name in failing:
                f.write("failed %s\n" % name)
    return 1 if failing else 0


if __name__ == "__main__":
    status = main()
    sys.stdout.flush()
    sys.stderr.flush()
    # The results are written: end here, without Blender's teardown, which is not what these tests check.
    # Blender 3.4 once crashed in it (a segmentation fault with no frame, Python's or Blender's, after every
    # test had passed), and a crash there would fail a run whose tests all passed.
    os._exit(status)
