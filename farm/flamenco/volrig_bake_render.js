// SPDX-License-Identifier: GPL-3.0-or-later
//
// Flamenco 3 custom job type: bake a scene's volrig volumes, then render them, split into chunks of frames.
//
// Install: copy this file into the Flamenco Manager's `scripts/` folder (next to flamenco-manager) and restart
// it; the Blender add-on then offers "volrig Bake + Render" as a job type. Every worker needs Blender and the
// volrig command line (`volrig_cmd`, default `python3 -m volrig`, with the volrig add-on installed in Blender or
// importable), and the .blend with its `<blend>_volrig/` cache folder on shared storage.
//
// The job:
//   prepare        volrig bake scene.blend --frames <first>     bakes the first frame and saves the .blend, so
//                                                               its Volume objects play the frame sequence
//   bake-A-B       volrig bake scene.blend --frames A-B --no-save   (depends on prepare; one per chunk)
//   render-A-B     blender -b scene.blend --render-frame A..B      (depends on bake-A-B only)
// Bake chunks never save the .blend (several run at once); every frame is independent and written atomically.

const JOB_TYPE = {
    label: "volrig Bake + Render",
    description: "Bake the scene's volrig volumes (volrig bake) in chunks of frames, and render each chunk once " +
        "its bake is done",
    settings: [
        { key: "frames", type: "string", required: true,
          eval: "f'{C.scene.frame_start}-{C.scene.frame_end}'",
          evalInfo: { showLinkButton: true, description: "Scene frame range" },
          description: "Frames to bake and render: '1-48', '1-10,20-30', '7'" },
        { key: "chunk_size", type: "int32", default: 10, propargs: { min: 1 }, visible: "submission",
          description: "Frames per bake task (and per render task)" },
        { key: "bake_mode", type: "string", default: "",
          choices: ["", "linear", "dual_quaternion", "rigid"], visible: "submission",
          description: "Deform mode for the bake; empty: each Volume object's own" },
        { key: "force", type: "bool", default: false, visible: "submission",
          description: "Re-bake frames whose pose did not change, too" },
        { key: "volrig_cmd", type: "string", default: "python3 -m volrig", visible: "submission",
          description: "The volrig command line on the workers (program and leading arguments)" },
        { key: "addon", type: "string", subtype: "file_path", default: "", visible: "submission",
          description: "The volrig add-on zip (or a folder holding volrig_addon) on shared storage, for " +
              "`volrig bake --addon`; empty: the one the worker's volrig finds, else Blender's installed add-on" },
        { key: "render_output_path", type: "string", subtype: "file_path", required: false,
          eval: "C.scene.render.filepath", visible: "submission",
          description: "Where frames are rendered (empty: the .blend's own output path)" },
        // Automatically evaluated settings:
        { key: "blendfile", type: "string", required: true, visible: "web",
          description: "Path of the .blend file (on shared storage)" },
    ],
};

// "1-10,20, 31-35" -> [[1, 10], [20, 20], [31, 35]]: sorted, merged ranges; throws on anything else.
function volrigFrameRanges(text) {
    const frames = [];
    for (const part of String(text).split(",")) {
        const p = part.trim();
        if (p === "") continue;
        const m = /^(-?\d+)\s*(?:(?:-|\.\.)\s*(-?\d+))?$/.exec(p);
        if (!m) throw `volrig: bad frame range "${p}" in "${text}" (use 1-48 or 1-10,20)`;
        const a = parseInt(m[1], 10), b = m[2] === undefined ? a : parseInt(m[2], 10);
        if (b < a) throw `volrig: frame range "${p}" runs backwards`;
        frames.push([a, b]);
    }
    if (frames.length === 0) throw `volrig: no frames in "${text}"`;
    frames.sort((x, y) => x[0] - y[0]);
    const merged = [frames[0].slice()];
    for (const [a, b] of frames.slice(1)) {
        const last = merged[merged.length - 1];
        if (a <= last[1] + 1) last[1] = Math.max(last[1], b);
        else merged.push([a, b]);
    }
    return merged;
}

// Ranges cut into chunks of at most `size` consecutive frames: [[first, last], ...].
function volrigChunks(text, size) {
    size = Math.max(1, Math.floor(Number(size) || 1));
    const chunks = [];
    for (const [a, b] of volrigFrameRanges(text)) {
        for (let s = a; s <= b; s += size) chunks.push([s, Math.min(b, s + size - 1)]);
    }
    return chunks;
}

function volrigCommand(settings, frames, save) {
    const words = String(settings.volrig_cmd || "python3 -m volrig").trim().split(/\s+/);
    let args = words.slice(1).concat(["bake", settings.blendfile, "--frames", frames, "--blender", "{blender}"]);
    if (!save) args.push("--no-save");
    if (settings.bake_mode) args = args.concat(["--mode", settings.bake_mode]);
    if (settings.force) args.push("--force");
    if (settings.addon) args = args.concat(["--addon", settings.addon]);
    return author.Command("exec", { exe: words[0], args: args });
}

function compileJob(job) {
    const settings = job.settings;
    if (!settings.blendfile) throw "volrig: no blendfile";
    const chunks = volrigChunks(settings.frames, settings.chunk_size);
    print(`volrig: ${chunks.length} bake + render chunk(s) of ${settings.blendfile}, frames ${settings.frames}`);

    const prepare = author.Task("prepare", "misc");
    prepare.addCommand(volrigCommand(settings, String(chunks[0][0]), true));
    job.addTask(prepare);

    for (const [a, b] of chunks) {
        const span = a === b ? `${a}` : `${a}-${b}`;
        const bake = author.Task(`bake-${span}`, "misc");
        bake.addCommand(volrigCommand(settings, span, false));
        bake.addDependency(prepare);
        job.addTask(bake);

        const render = author.Task(`render-${span}`, "blender");
        const args = [];
        if (settings.render_output_path) args.push("--render-output", settings.render_output_path);
        args.push("--render-frame", a === b ? `${a}` : `${a}..${b}`);
        render.addCommand(author.Command("blender-render", {
            exe: "{blender}",
            exeArgs: "{blenderArgs}",
            argsBefore: [],
            blendfile: settings.blendfile,
            args: args,
        }));
        render.addDependency(bake);
        job.addTask(render);
    }
}
