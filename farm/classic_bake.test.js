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

function commandLine(task) {
    assert.equal(task.commands.length, 1);
    const { name, parameters } = task.commands[0];
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
    assert.throws(() => compile(SCRIPT, { ...SAMPLE, tiles: 4 }), /cannot split a bake into tiles yet/);
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
