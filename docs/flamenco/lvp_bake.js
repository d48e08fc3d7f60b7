// SPDX-License-Identifier: GPL-3.0-or-later
// Flamenco job type: bake Volume Preservation to PC2 point caches, in chunks, then merge (docs/baking.md).
// Copy into the "scripts" folder next to flamenco-manager and restart it. Workers need Blender 4.2+
// with the Local Volume Preservation extension enabled (for Blender 3.4 see docs/baking.md).

const JOB_TYPE = {
    label: "Volume Preservation Bake",
    settings: [
        { key: "objects", type: "string", required: true,
          eval: "' '.join(o.name for o in C.selected_objects if o.type == 'MESH')",
          description: "Objects to bake, separated by spaces" },
        { key: "frames", type: "string", required: true,
          eval: "f'{C.scene.frame_start}-{C.scene.frame_end}'",
          description: "Frame range to bake, e.g. '1-250'" },
        { key: "chunk_size", type: "int32", default: 24, visible: "submission",
          description: "Frames baked by one task" },
        { key: "output_dir", type: "string", subtype: "dir_path", required: true, visible: "submission",
          description: "Shared directory for <object>.pc2 (and the parts while the job runs)" },
        { key: "blendfile", type: "string", required: true, visible: "web",
          description: "Path of the .blend file to bake" },
    ]
};

function bakeCommand(settings, frames, mode) {
    return author.Command("blender-render", {
        exe: "{blender}",
        exeArgs: "{blenderArgs}",
        argsBefore: [],
        blendfile: settings.blendfile,
        args: ["-c", "lvp_bake", "--objects"].concat(settings.objects.split(" ").filter((name) => name))
            .concat(["--frames", frames, "--output", settings.output_dir, mode]),
    });
}

function compileJob(job) {
    const settings = job.settings;
    const merge = author.Task("merge", "blender");
    merge.addCommand(bakeCommand(settings, settings.frames, "--merge"));
    for (const chunk of frameChunker(settings.frames, settings.chunk_size)) {
        const task = author.Task(`bake-${chunk}`, "blender");
        task.addCommand(bakeCommand(settings, chunk, "--chunk"));
        job.addTask(task);
        merge.addDependency(task);
    }
    job.addTask(merge);
}
