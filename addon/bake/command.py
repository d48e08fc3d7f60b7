# SPDX-License-Identifier: GPL-3.0-or-later
"""The headless bake command (docs/baking.md):

    blender -b shot.blend -c lvp_bake --objects Giraffe --frames 1-250 --output /shared/cache/shot --jobs 2
    blender -b shot.blend --python <add-on folder>/bake/lvp_bake.py -- --objects Giraffe ...   (Blender 3.4+)

Blender 4.2+ registers it with bpy.utils.register_cli_command; bake/lvp_bake.py gives the same command
to any Blender through --python. Progress goes to stderr; the exit status is 0 on success, 1 when the
bake failed (with a message that says why) and 2 for bad arguments.

Modes: by default, bake what is missing and merge into <output>/<object>.pc2 (and .abc when Blender
has Alembic). --chunk only bakes the frames into parts (a render-farm task); --merge only merges (the
farm's last task) and fails, naming them, when frames are missing. --jobs N runs N Blender processes,
each on a slice of the missing frames (as chunks), and merges their parts.
"""

import argparse
import os
import signal
import subprocess
import sys
import threading
import time
import traceback

import bpy

from .. import blender_api
from . import engine
from . import pc2
from .capture import BakeError, find_objects

COMMAND = "lvp_bake"
SCRIPT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "lvp_bake.py")
PROGRESS_PREFIX = "lvp_bake:progress "
# Blender options of this process that the --jobs processes get too.
MIRRORED_FLAGS = ("--factory-startup", "-noaudio", "-y", "--enable-autoexec", "-Y", "--disable-autoexec")


class UsageError(Exception):
    pass


class Parser(argparse.ArgumentParser):
    def error(self, message):
        raise UsageError(message)


def _job_count(text):
    try:
        count = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError("%r is not a whole number" % text) from None
    if count < 1:
        raise argparse.ArgumentTypeError("must be 1 or more, not %d" % count)
    return count


def make_parser():
    parser = Parser(
        prog="blender -b FILE.blend -c %s" % COMMAND,
        description="Bake the volume-corrected animation of objects to PC2 point caches (one <object>.pc2 per "
                    "object, object local space, the mesh as it leaves Volume Preservation).")
    parser.add_argument("--objects", nargs="+", metavar="NAME", default=[],
                        help="objects to bake (default: every object of the scene with Volume Preservation)")
    parser.add_argument("--frames", metavar="FIRST-LAST",
                        help="frames to bake, e.g. 1-250 (default: the scene's frame range)")
    parser.add_argument("--output", required=True, metavar="DIR",
                        help="directory for <object>.pc2 (or a .pc2 file name when baking one object); "
                             "// is relative to the .blend")
    parser.add_argument("--jobs", type=_job_count, default=1, metavar="N",
                        help="Blender processes baking at once, each on a slice of the frames (default 1)")
    mode = parser.add_mutually_exclusive_group()
    mode.add_argument("--chunk", action="store_true",
                      help="only bake these frames into parts, do not merge (one task of a render farm)")
    mode.add_argument("--merge", action="store_true",
                      help="only merge the parts baked by --chunk tasks into one file per object")
    parser.add_argument("--restart", action="store_true",
                        help="throw away frames baked before instead of resuming")
    parser.add_argument("--no-alembic", action="store_true", help="do not write <object>.abc")
    parser.add_argument("--worker", action="store_true", help=argparse.SUPPRESS)
    parser.add_argument("--source", help=argparse.SUPPRESS)
    return parser


def say(message):
    sys.stderr.write("%s: %s\n" % (COMMAND, message))
    sys.stderr.flush()


def run(argv):
    """The command: returns the exit status."""
    try:
        arguments = make_parser().parse_args(list(argv))
    except UsageError as error:
        say("error: %s (see -c %s --help)" % (error, COMMAND))
        return 2
    except SystemExit as exit_request:  # --help
        return exit_request.code or 0
    try:
        return _run(arguments)
    except pc2.DiskFullError as error:
        say("error: %s. Free some space (or choose another --output) and run the same command again: the frames "
            "already baked are kept and only the missing ones are baked" % error)
    except pc2.MissingFramesError as error:
        say("error: %s: bake them first (run the --chunk tasks for them, or this command without --merge)" % error)
    except (BakeError, pc2.PC2Error) as error:
        say("error: %s" % error)
    except KeyboardInterrupt:
        say("interrupted: the frames already baked are kept; run the same command again to finish")
        return 130
    except Exception:
        traceback.print_exc()
        say("error: the bake failed (see the traceback above)")
    return 1


def _frames(arguments, scene):
    if arguments.frames is None:
        return pc2.parse_frames("%d-%d" % (scene.frame_start, scene.frame_end))
    return pc2.parse_frames(arguments.frames)


def _run(arguments):
    scene = bpy.context.scene
    frames = _frames(arguments, scene)
    objects = find_objects(scene, arguments.objects)
    if not bpy.data.filepath and (arguments.jobs > 1 or arguments.chunk or arguments.merge):
        raise BakeError("--jobs, --chunk and --merge need a saved .blend file")
    chunk = arguments.chunk or arguments.worker
    bake = engine.Bake(scene, objects, frames, arguments.output, source=arguments.source, owner=not chunk, log=say)
    if not chunk and frames != list(range(frames[0], frames[-1] + 1)):
        raise BakeError("a PC2 file holds one range of frames: %s has gaps (use --chunk for a list of frames)"
                        % pc2.format_frames(frames))

    if arguments.merge:
        bake.check_output()
        return _merge(bake, arguments)

    work = bake.plan(restart=arguments.restart)
    if not arguments.worker:
        for target in bake.targets:
            say("%s (%d vertices) -> %s" % (target.name, target.reader.vertex_count, target.final_path))
        say("frames %s: %d already baked, %d to bake%s" % (
            pc2.format_frames(frames), len(frames) - len(work), len(work),
            " with %d jobs" % min(arguments.jobs, len(work)) if arguments.jobs > 1 and len(work) > 1 else ""))
    if work:
        if arguments.jobs > 1 and len(work) > 1 and not arguments.worker:
            _run_jobs(bake, arguments)
        else:
            _bake_here(bake, arguments.worker)
    if chunk:
        if not arguments.worker:
            say("chunk done: frames %s are baked into parts; merge them with --merge" % pc2.format_frames(frames))
        return 0
    return _merge(bake, arguments)


def _bake_here(bake, worker):
    total = len(bake.work)
    progress = None if worker else engine.Progress(total)
    last_report = 0.0
    try:
        bake.start()
        while not bake.done:
            bake.step()
            if progress is not None:
                progress.update(bake.frames_done)
            elif time.monotonic() - last_report >= 0.2 or bake.done:
                last_report = time.monotonic()
                sys.stderr.write("%s%d %d\n" % (PROGRESS_PREFIX, bake.frames_done, total))
                sys.stderr.flush()
        bake.finish_parts()
    finally:
        bake.close()


def _merge(bake, arguments):
    written = bake.merge()
    for path in written:
        header = pc2.read_header(path)
        say("wrote %s (%d points, %d frames from %g)" % (path, header.num_points, header.num_samples,
                                                       header.start_frame))
    if not arguments.no_alembic:
        objects = [target.reader.obj for target in bake.targets]
        for path in engine.export_alembic(bpy.context, objects, bake.frames[0], bake.frames[-1], bake.directory,
                                          say):
            say("wrote %s" % path)
    return 0


# ---- several Blender processes -------------------------------------------------------------


def child_command(arguments):
    """The command line of one --jobs process: this Blender, this .blend, the bake script, arguments."""
    command = [bpy.app.binary_path, "-b"]
    command += [flag for flag in MIRRORED_FLAGS if flag in sys.argv]
    command += [bpy.data.filepath, "--python", SCRIPT, "--"] + list(arguments)
    return command


def _die_with_parent():
    """In the child: get SIGTERM when the parent Blender dies (Linux), so no job outlives a killed bake."""
    try:
        import ctypes
        libc = ctypes.CDLL(None, use_errno=True)
        libc.prctl(1, signal.SIGTERM)  # PR_SET_PDEATHSIG
    except Exception:
        pass


def _run_jobs(bake, arguments):
    slices = pc2.split_even(bake.work, arguments.jobs)
    names = [target.name for target in bake.targets]
    output = bake.targets[0].final_path if arguments.output.lower().endswith(".pc2") else bake.directory
    total = len(bake.work)
    done = [0] * len(slices)
    processes = []
    readers = []
    lock = threading.Lock()

    def read_stderr(index, stream):
        for line in stream:
            if line.startswith(PROGRESS_PREFIX):
                with lock:
                    done[index] = int(line[len(PROGRESS_PREFIX):].split()[0])
            else:
                sys.stderr.write("%s [job %d]: %s" % (COMMAND, index + 1, line if line.endswith("\n") else line + "\n"))
                sys.stderr.flush()

    for index, frames in enumerate(slices):
        child = ["--objects"] + names + ["--frames", pc2.format_frames(frames), "--output", output, "--worker",
                                         "--source", bake.source]
        say("job %d: frames %s" % (index + 1, pc2.format_frames(frames)))
        process = subprocess.Popen(child_command(child), stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL,
                                   stderr=subprocess.PIPE, universal_newlines=True, preexec_fn=_die_with_parent)
        processes.append(process)
        reader = threading.Thread(target=read_stderr, args=(index, process.stderr), daemon=True)
        reader.start()
        readers.append(reader)

    progress = engine.Progress(total)
    try:
        while any(process.poll() is None for process in processes):
            time.sleep(0.1)
            with lock:
                progress.update(sum(done))
    except BaseException:
        for process in processes:
            if process.poll() is None:
                process.terminate()
        raise
    for reader in readers:
        reader.join(timeout=5)
    failed = [(index, process.returncode) for index, process in enumerate(processes) if process.returncode != 0]
    if failed:
        raise BakeError("; ".join("job %d (frames %s) failed with exit status %d" % (
            index + 1, pc2.format_frames(slices[index]), status) for index, status in failed) +
            ": the frames the jobs finished are kept, run the same command again to bake the rest")
    with lock:
        if progress.printed != sum(done):
            progress.update(sum(done), force=True)


# ---- registration --------------------------------------------------------------------------

_handle = None


def register():
    global _handle
    if blender_api.has_cli_commands() and _handle is None:
        _handle = bpy.utils.register_cli_command(COMMAND, run)


def unregister():
    global _handle
    if _handle is not None:
        bpy.utils.unregister_cli_command(_handle)
        _handle = None
