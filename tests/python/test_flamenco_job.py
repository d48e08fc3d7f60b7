"""The Flamenco job type docs/flamenco/lvp_bake.js, compiled with Node.js against a stand-in for Flamenco's
job-compiler API (author.Task, author.Command, frameChunker, job.addTask): it must make exactly the
commands docs/baking.md shows (which tests/blender/test_bake.py TestDocs runs in Blender), with the merge
task depending on every chunk. Skipped when node is not installed.

Run one:   /usr/bin/python3 -m unittest -v test_flamenco_job   (from tests/python)
"""

import json
import os
import shutil
import subprocess
import unittest

HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.dirname(os.path.dirname(HERE))
JOB_TYPE = os.path.join(REPO, "docs", "flamenco", "lvp_bake.js")
DOC = os.path.join(REPO, "docs", "baking.md")

# Flamenco's behaviour that the job type relies on: frame chunks "a-b" of chunk_size frames, and the
# blender-render command line = exe, exeArgs, argsBefore, blendfile, args.
HARNESS = r"""
const fs = require("fs");
const tasks = [];
const author = {
    Task(name, type) {
        const task = {name, type, commands: [], dependencies: [],
                      addCommand(command) { this.commands.push(command); },
                      addDependency(other) { this.dependencies.push(other.name); }};
        return task;
    },
    Command(type, parameters) { return {type, parameters}; },
};
function frameChunker(frames, size) {
    const [first, last] = frames.split("-").map(Number);
    const chunks = [];
    for (let start = first; start <= last; start += size) {
        const end = Math.min(last, start + size - 1);
        chunks.push(start === end ? `${start}` : `${start}-${end}`);
    }
    return chunks;
}
function print() {}
eval(fs.readFileSync(process.argv[1], "utf8") + "\nthis.compileJob = compileJob; this.JOB_TYPE = JOB_TYPE;");
const job = {settings: JSON.parse(process.argv[2]), addTask(task) { tasks.push(task); }};
compileJob(job);
console.log(JSON.stringify(tasks.map((task) => ({
    name: task.name, dependencies: task.dependencies,
    commands: task.commands.map((command) => [command.type, command.parameters.exe, command.parameters.exeArgs]
        .concat(command.parameters.argsBefore, [command.parameters.blendfile], command.parameters.args)),
}))));
"""


def doc_farm_commands():
    with open(DOC) as file:
        text = file.read()
    section = text[text.index("## Render farms"):]
    block = section[section.index("```sh") + len("```sh"):]
    block = block[:block.index("```")]
    return [line.strip() for line in block.splitlines() if line.strip()]


@unittest.skipIf(shutil.which("node") is None, "node (Node.js) is not installed")
class TestFlamencoJobType(unittest.TestCase):

    def compile(self, settings):
        completed = subprocess.run(["node", "-e", HARNESS, JOB_TYPE, json.dumps(settings)], stdout=subprocess.PIPE,
                                   stderr=subprocess.STDOUT, universal_newlines=True, timeout=60)
        self.assertEqual(completed.returncode, 0, completed.stdout)
        return json.loads(completed.stdout)

    def test_commands_are_the_documented_ones(self):
        tasks = self.compile({"objects": "Giraffe", "frames": "1-48", "chunk_size": 24,
                              "output_dir": "/shared/cache/shot", "blendfile": "shot.blend"})
        lines = []
        for task in tasks:
            self.assertEqual(len(task["commands"]), 1)
            kind, exe, exe_args, *arguments = task["commands"][0]
            self.assertEqual((kind, exe, exe_args), ("blender-render", "{blender}", "{blenderArgs}"))
            # Flamenco's default blenderArgs are "-b -y".
            lines.append(" ".join(["blender", "-b", "-y"] + arguments))
        self.assertEqual(sorted(lines), sorted(doc_farm_commands()))
        merge = [task for task in tasks if task["name"] == "merge"]
        self.assertEqual(len(merge), 1)
        self.assertEqual(sorted(merge[0]["dependencies"]), sorted(t["name"] for t in tasks if t["name"] != "merge"))
        self.assertEqual(tasks[-1]["name"], "merge")

    def test_several_objects_and_uneven_chunks(self):
        tasks = self.compile({"objects": "Giraffe  Horse", "frames": "1-50", "chunk_size": 20,
                              "output_dir": "/out", "blendfile": "a.blend"})
        commands = [task["commands"][0] for task in tasks if task["name"] != "merge"]
        chunks = [command[command.index("--frames") + 1] for command in commands]
        self.assertEqual(chunks, ["1-20", "21-40", "41-50"])
        self.assertIn("Horse", tasks[0]["commands"][0])
        self.assertEqual(tasks[0]["commands"][0][-1], "--chunk")


if __name__ == "__main__":
    unittest.main()
