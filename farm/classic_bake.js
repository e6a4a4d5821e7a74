// SPDX-License-Identifier: GPL-3.0-or-later
//
// Flamenco job type "Classic Bake": one technique of Classic Bake on one .blend, on a render farm.
//
// A job compiles into three stages (farm/README.md):
//   prepare  `blender -b -c classic_bake info SCENE --out OUT/info` (the scene opens on a worker
//            and what it holds is recorded); or, with several tiles of a technique that has one,
//            its own prepare step `TECHNIQUE SCENE --out OUT/TECHNIQUE --tile prepare [...]`
//            (radiosity: the solve, saved once for the tiles);
//   bake     one task per tile, `blender -b -c classic_bake TECHNIQUE SCENE --out OUT/TECHNIQUE
//            [--resolution W H] [ARGS] [--tile K/N]`, each depending on prepare;
//   merge    after every tile: with several, `classic_bake merge OUT/TECHNIQUE` (the tiles into
//            the outputs one run writes); then `classic_bake report OUT`, one HTML page of the runs.

const TECHNIQUES = ["lightmap-uv", "texture", "trace", "envmap", "bump", "shadowmap", "radiosity",
                    "hybrid", "normalmap"];
// The techniques whose command line takes `--tile K/N`, and whether their tiles need
// `--tile prepare` first (jobs/tiles.py).
const TILED = { radiosity: { prepare: true }, trace: { prepare: false },
                envmap: { prepare: false }, texture: { prepare: false } };
const MAX_TILES = 256;

const JOB_TYPE = {
    label: "Classic Bake",
    description: "Bake one Classic Bake technique on the farm: prepare, bake, merge into a report",
    settings: [
        // Settings for artists to determine:
        { key: "technique", type: "string", required: true, default: "trace", choices: TECHNIQUES,
          description: "Which Classic Bake command runs (python -m classic_bake --help lists them)" },
        { key: "tiles", type: "int32", default: 1, propargs: { min: 1, max: 256 },
          description: "Tasks the bake is split into (above 1: radiosity, whose tiles share its " +
                       "objects' lightmaps after one solve, texture, whose tiles share the lightmaps, " +
                       "trace, whose tiles share the rows, or envmap, whose tiles share the cube " +
                       "faces and whose merge renders the view)" },
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
    if (tiles > MAX_TILES) {
        throw `tiles = ${tiles}: at most ${MAX_TILES}`;
    }
    const tiled = TILED[technique];
    if (tiles > 1 && !tiled) {
        throw `tiles = ${tiles}: ${technique} cannot be split into tiles (tiles above 1: ` +
              `${Object.keys(TILED).join(", ")}); use tiles = 1`;
    }
    const out = outputPath(job);
    settings.output_path = out;  // the job shows where its output went
    const runFolder = path.join(out, technique);
    const bakeArgs = [technique, settings.blendfile, "--out", runFolder].concat(
        resolutionArgs(settings.resolution), splitArgs(settings.args));

    const prepare = tiles > 1 && tiled.prepare
        ? bakeTask("prepare", bakeArgs.concat(["--tile", "prepare"]))
        : bakeTask("prepare", ["info", settings.blendfile, "--out", path.join(out, "info")]);
    job.addTask(prepare);

    const bakes = [];
    for (let tile = 1; tile <= tiles; tile++) {
        const task = tiles > 1
            ? bakeTask(`bake-${technique}-${tile}-of-${tiles}`, bakeArgs.concat(["--tile", `${tile}/${tiles}`]))
            : bakeTask(`bake-${technique}`, bakeArgs);
        task.addDependency(prepare);
        job.addTask(task);
        bakes.push(task);
    }

    const steps = tiles > 1 ? [["merge", runFolder]] : [];
    steps.push(["report", out, "--title", `${job.name}: ${technique}`]);
    const merge = bakeTask("merge", ...steps);
    for (const task of bakes) {
        merge.addDependency(task);
    }
    job.addTask(merge);
}

// A "blender" task running one command, or several in turn: `{blender} {blenderArgs} -b -c
// classic_bake ARGS...` each. The blend file goes to the command, not to Blender (`blendfile`
// empty), as `blender -c` expects.
function bakeTask(name, ...commands) {
    const task = author.Task(name, "blender");
    for (const commandArgs of commands) {
        task.addCommand(author.Command("blender-render", {
            exe: "{blender}",
            exeArgs: "{blenderArgs}",
            argsBefore: ["-b"],
            blendfile: "",
            args: ["-c", "classic_bake"].concat(commandArgs),
        }));
    }
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
