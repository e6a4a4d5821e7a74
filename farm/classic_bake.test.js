// node --test farm/ : the Classic Bake job type compiled by farm/harness.js.

"use strict";

const test = require("node:test");
const assert = require("node:assert/strict");
const nodePath = require("node:path");
const { compile, load } = require("./harness.js");

const SCRIPT = nodePath.join(__dirname, "classic_bake.js");
const SAMPLE = {
    technique: "shadowmap", blendfile: "/farm/scenes/shadows.blend",
    output_root: "/farm/out", resolution: "320 240", args: "--pcf 3 --eps-mode 'auto'",
};

function commandLine(task, k = 0, count = 1) {
    assert.equal(task.commands.length, count);
    const { name, parameters } = task.commands[k];
    assert.equal(name, "blender-render");
    assert.equal(parameters.exe, "{blender}");
    assert.equal(parameters.exeArgs, "{blenderArgs}");
    assert.equal(parameters.blendfile, "");  // the scene goes to the command, not to Blender
    return [...parameters.argsBefore, ...parameters.args];
}

test("the job type declares its settings", () => {
    const { context } = load(SCRIPT);
    const keys = context.JOB_TYPE.settings.map((s) => s.key);
    for (const key of ["technique", "tiles", "blendfile", "output_root", "resolution", "args"]) {
        assert.ok(keys.includes(key), key);
    }
    const technique = context.JOB_TYPE.settings.find((s) => s.key === "technique");
    assert.ok(technique.choices.includes("radiosity") && technique.choices.includes("trace"));
});

test("a sample bake compiles to prepare, bake and merge with their dependencies", () => {
    const { job } = compile(SCRIPT, SAMPLE, "shadows-job");
    assert.deepEqual(job.tasks.map((t) => t.name), ["prepare", "bake-shadowmap", "merge"]);
    assert.ok(job.tasks.every((t) => t.type === "blender"));
    const [prepare, bake, merge] = job.tasks;
    assert.deepEqual(commandLine(prepare), ["-b", "-c", "classic_bake", "info",
        "/farm/scenes/shadows.blend", "--out", "/farm/out/shadows-job/info"]);
    assert.deepEqual(commandLine(bake), ["-b", "-c", "classic_bake", "shadowmap",
        "/farm/scenes/shadows.blend", "--out", "/farm/out/shadows-job/shadowmap",
        "--resolution", "320", "240", "--pcf", "3", "--eps-mode", "auto"]);
    assert.deepEqual(commandLine(merge), ["-b", "-c", "classic_bake", "report",
        "/farm/out/shadows-job", "--title", "shadows-job: shadowmap"]);
    assert.deepEqual(prepare.dependencies, []);
    assert.deepEqual(bake.dependencies.map((t) => t.uuid), [prepare.uuid]);
    assert.deepEqual(merge.dependencies.map((t) => t.uuid), [bake.uuid]);
    assert.equal(job.settings.output_path, "/farm/out/shadows-job");
});

test("a tiled radiosity bake compiles to the solve, a task per tile and the merge", () => {
    const settings = { ...SAMPLE, technique: "radiosity", blendfile: "/farm/scenes/cornell.blend",
                       tiles: 3, args: "--patches 400" };
    const { job } = compile(SCRIPT, settings, "cornell");
    assert.deepEqual(job.tasks.map((t) => t.name), ["prepare", "bake-radiosity-1-of-3",
        "bake-radiosity-2-of-3", "bake-radiosity-3-of-3", "merge"]);
    const [prepare, ...rest] = job.tasks;
    const merge = rest.pop();
    const bake = ["-b", "-c", "classic_bake", "radiosity", "/farm/scenes/cornell.blend", "--out",
                  "/farm/out/cornell/radiosity", "--resolution", "320", "240", "--patches", "400"];
    assert.deepEqual(commandLine(prepare), [...bake, "--tile", "prepare"]);
    rest.forEach((task, k) => {
        assert.deepEqual(commandLine(task), [...bake, "--tile", `${k + 1}/3`]);
        assert.deepEqual(task.dependencies.map((t) => t.uuid), [prepare.uuid]);
    });
    // The merge puts the tiles together, then the report reads the merged run.
    assert.deepEqual(commandLine(merge, 0, 2), ["-b", "-c", "classic_bake", "merge",
        "/farm/out/cornell/radiosity"]);
    assert.deepEqual(commandLine(merge, 1, 2), ["-b", "-c", "classic_bake", "report",
        "/farm/out/cornell", "--title", "cornell: radiosity"]);
    assert.deepEqual(merge.dependencies.map((t) => t.uuid).sort(), rest.map((t) => t.uuid).sort());
    assert.deepEqual(prepare.dependencies, []);
});

test("a tiled trace needs no prepare step of its own: info, a task per rows' share, merge", () => {
    const { job } = compile(SCRIPT, { ...SAMPLE, technique: "trace", tiles: 2, args: "" }, "t");
    assert.deepEqual(job.tasks.map((t) => t.name), ["prepare", "bake-trace-1-of-2", "bake-trace-2-of-2",
        "merge"]);
    assert.deepEqual(commandLine(job.tasks[0]).slice(3, 4), ["info"]);
    assert.deepEqual(commandLine(job.tasks[2]).slice(-2), ["--tile", "2/2"]);
    assert.deepEqual(commandLine(job.tasks[3], 0, 2).slice(3), ["merge", "/farm/out/t/trace"]);
});

test("a tiled envmap shares the cube faces: info, a task per share, merge renders the view", () => {
    const { job } = compile(SCRIPT, { ...SAMPLE, technique: "envmap", tiles: 3, args: "--face-size 64" }, "e");
    assert.deepEqual(job.tasks.map((t) => t.name), ["prepare", "bake-envmap-1-of-3", "bake-envmap-2-of-3",
        "bake-envmap-3-of-3", "merge"]);
    assert.deepEqual(commandLine(job.tasks[0]).slice(3, 4), ["info"]);
    assert.deepEqual(commandLine(job.tasks[2]).slice(-4), ["--face-size", "64", "--tile", "2/3"]);
    assert.deepEqual(commandLine(job.tasks[4], 0, 2).slice(3), ["merge", "/farm/out/e/envmap"]);
    assert.equal(job.tasks[4].dependencies.length, 3);
});

test("a tiled texture bake shares the objects' lightmaps without a prepare step", () => {
    const { job } = compile(SCRIPT, { ...SAMPLE, technique: "texture", tiles: 2, args: "" }, "x");
    assert.deepEqual(job.tasks.map((t) => t.name), ["prepare", "bake-texture-1-of-2",
        "bake-texture-2-of-2", "merge"]);
    assert.deepEqual(commandLine(job.tasks[0]).slice(3, 4), ["info"]);
    assert.deepEqual(commandLine(job.tasks[3], 0, 2).slice(3), ["merge", "/farm/out/x/texture"]);
});

test("defaults: the scene's own resolution, no extra options, one tile", () => {
    const { job } = compile(SCRIPT, { blendfile: "/s/cornell box.blend", output_root: "/o" }, "j");
    const bake = job.tasks[1];
    assert.equal(bake.name, "bake-trace");
    assert.deepEqual(commandLine(bake).slice(3), ["trace", "/s/cornell box.blend", "--out", "/o/j/trace"]);
});

test("an evaluated output path is used as it is", () => {
    const { job } = compile(SCRIPT, { ...SAMPLE, output_path: "/evaluated/here" });
    assert.deepEqual(commandLine(job.tasks[0]).slice(-2), ["--out", "/evaluated/here/info"]);
});

test("bad settings are refused with a message", () => {
    assert.throws(() => compile(SCRIPT, { ...SAMPLE, technique: "render" }), /unknown technique "render"/);
    assert.throws(() => compile(SCRIPT, { ...SAMPLE, resolution: "big" }), /resolution must be 'W H'/);
    assert.throws(() => compile(SCRIPT, { ...SAMPLE, tiles: 0 }), /at least 1/);
    assert.throws(() => compile(SCRIPT, { ...SAMPLE, tiles: 4 }), /shadowmap cannot be split into tiles/);
    assert.throws(() => compile(SCRIPT, { ...SAMPLE, technique: "radiosity", tiles: 2.5 }), /whole number/);
    assert.throws(() => compile(SCRIPT, { ...SAMPLE, technique: "radiosity", tiles: 999 }), /at most 256/);
    assert.throws(() => compile(SCRIPT, { technique: "trace", output_root: "/o" }), /blendfile/);
});

test("the harness behaves as Flamenco's author module where a script could tell", () => {
    const { context } = load(SCRIPT);
    const { author } = require("./harness.js");
    assert.throws(() => author.Task("", "blender"), /name is required/);
    assert.throws(() => author.Task("x", " "), /type is required/);
    const { makeJob, checkJob } = require("./harness.js");
    const job = makeJob("j", {});
    const a = author.Task("a", "misc");
    const b = author.Task("b", "misc");
    job.addTask(a);
    a.addDependency(b);  // after addTask: lost, as in Go
    assert.deepEqual(job.tasks[0].dependencies, []);
    b.addDependency(a);
    job.addTask(b);
    checkJob(job);
    const orphan = author.Task("c", "misc");
    orphan.addDependency(author.Task("not-in-job", "misc"));
    job.addTask(orphan);
    assert.throws(() => checkJob(job), /not in the job/);
    assert.equal(typeof context.compileJob, "function");
});
