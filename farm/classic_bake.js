// SPDX-License-Identifier: GPL-3.0-or-later
//
// Flamenco job type "Classic Bake": one technique of Classic Bake on one .blend, on a render farm.
//
// A job compiles into three stages (farm/README.md):
//   prepare  `blender -b -c classic_bake info SCENE --out OUT/info`: the scene opens on a
//            worker and what it holds is recorded (OUT/info/info.json);
//   bake     one task per tile, `blender -b -c classic_bake TECHNIQUE SCENE --out OUT/TECHNIQUE
//            [--resolution W H] [ARGS]`, each depending on prepare;
//   merge    `blender -b -c classic_bake report OUT`, one HTML page of the runs, after every tile.
// Only one tile per bake for now: the command line has no `--tile` option yet (splitting a bake
// into texel ranges, cube faces or camera rows is future work), so `tiles` above 1 is refused
// with a message rather than compiled into commands the workers would fail.

const TECHNIQUES = ["lightmap-uv", "texture", "trace", "envmap", "bump", "shadowmap", "radiosity",
                    "hybrid", "normalmap"];
const MAX_TILES_SUPPORTED = 1;

const JOB_TYPE = {
    label: "Classic Bake",
    description: "Bake one Classic Bake technique on the farm: prepare, bake, merge into a report",
    settings: [
        // Settings for artists to determine:
        { key: "technique", type: "string", required: true, default: "trace", choices: TECHNIQUES,
          description: "Which Classic Bake command runs (python -m classic_bake --help lists them)" },
        { key: "tiles", type: "int32", default: 1, propargs: { min: 1, max: 256 },
          description: "Tasks the bake is split into (1 until the command line can tile)" },
        { key: "resolution", type: "string", default: "",
          description: "render.exr size 'W H'; empty: the scene's render size" },
        { key: "args", type: "string", default: "",
          description: "Further options of the technique's command, e.g. '--depth 4 --adaptive 2'" },
        { key: "output_root", type: "string", subtype: "dir_path", required: true,
          visible: "submission", description: "Folder the job's output folder is made in" },
        { key: "output_path", type: "string", subtype: "dir_path", editable: false,
          eval: "str(Path(abspath(settings.output_root), jobname))",
          description: "The job's output folder: one run folder per stage" },

        // Automatically evaluated settings:
        { key: "blendfile", type: "string", required: true, visible: "web",
          description: "Path of the .blend file to bake" },
    ],
};

function compileJob(job) {
    const settings = job.settings;
    const technique = settings.technique;
    if (TECHNIQUES.indexOf(technique) < 0) {
        throw `unknown technique "${technique}"; one of ${TECHNIQUES.join(", ")}`;
    }
    const tiles = settings.tiles === undefined ? 1 : Number(settings.tiles);
    if (!(tiles >= 1) || Math.floor(tiles) !== tiles) {
        throw `tiles must be a whole number of at least 1, got ${settings.tiles}`;
    }
    if (tiles > MAX_TILES_SUPPORTED) {
        throw `tiles = ${tiles}: classic_bake's command line cannot split a bake into tiles yet; ` +
              `use tiles = 1`;
    }
    const out = outputPath(job);
    settings.output_path = out;  // the job shows where its output went

    const prepare = bakeTask("prepare", ["info", settings.blendfile, "--out", path.join(out, "info")]);
    job.addTask(prepare);

    const bakes = [];
    for (let tile = 0; tile < tiles; tile++) {
        const args = [technique, settings.blendfile, "--out", path.join(out, technique)];
        const size = resolutionArgs(settings.resolution);
        const task = bakeTask(tiles > 1 ? `bake-${technique}-${tile + 1}-of-${tiles}` : `bake-${technique}`,
                              args.concat(size, splitArgs(settings.args)));
        task.addDependency(prepare);
        job.addTask(task);
        bakes.push(task);
    }

    const merge = bakeTask("merge", ["report", out, "--title", `${job.name}: ${technique}`]);
    for (const task of bakes) {
        merge.addDependency(task);
    }
    job.addTask(merge);
}

// A "blender" task of one command: `{blender} {blenderArgs} -b -c classic_bake ARGS...`. The
// blend file goes to the command, not to Blender (`blendfile` empty), as `blender -c` expects.
function bakeTask(name, commandArgs) {
    const task = author.Task(name, "blender");
    task.addCommand(author.Command("blender-render", {
        exe: "{blender}",
        exeArgs: "{blenderArgs}",
        argsBefore: ["-b"],
        blendfile: "",
        args: ["-c", "classic_bake"].concat(commandArgs),
    }));
    return task;
}

function outputPath(job) {
    const settings = job.settings;
    if (settings.output_path) {
        return settings.output_path;
    }
    if (!settings.output_root) {
        throw "no output_root setting";
    }
    return path.join(settings.output_root, job.name);
}

// "320 240" or "320x240" -> ["--resolution", "320", "240"]; "" -> [].
function resolutionArgs(text) {
    const value = (text || "").trim();
    if (!value) {
        return [];
    }
    const parts = value.split(/[\sx,]+/);
    if (parts.length !== 2 || !parts.every((p) => /^[1-9][0-9]*$/.test(p))) {
        throw `resolution must be 'W H', got "${text}"`;
    }
    return ["--resolution", parts[0], parts[1]];
}

// Split extra options on white space, keeping 'single' or "double" quoted parts together.
function splitArgs(text) {
    const found = [];
    const pattern = /"([^"]*)"|'([^']*)'|(\S+)/g;
    let match;
    while ((match = pattern.exec(text || "")) !== null) {
        found.push(match[1] !== undefined ? match[1] : match[2] !== undefined ? match[2] : match[3]);
    }
    return found;
}
