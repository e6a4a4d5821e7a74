// A stand-in for Flamenco Manager's job-compiler runtime, for testing job types with Node.
//
// It provides what a job compiler script sees in the Manager (Flamenco's
// internal/manager/job_compilers: author.go, and the `path` and `print` globals) with the same
// behaviour where a script could notice a difference:
//   author.Task(name, type)      name and type required (trimmed); priority 50; a UUID
//   author.Command(name, params) a command with its parameters
//   task.addCommand(command), task.addDependency(task)
//   job.addTask(task)            adds a COPY of the task as it is at that moment, as the Go
//                                side does (`append(aj.Tasks, *at)`): commands or dependencies
//                                added afterwards are lost, so a script must finish a task first
//   path.join/dirname/basename/stem, print, formatTimestampLocal
// `compile(script, settings)` loads a script, checks JOB_TYPE, fills in the settings' defaults
// as the Manager does and runs compileJob; `checkJob(job)` checks what the Manager would refuse
// (a dependency on a task that is not in the job, a cycle, a task name used twice).

"use strict";

const fs = require("node:fs");
const nodePath = require("node:path");
const vm = require("node:vm");
const crypto = require("node:crypto");

function makeTask(name, type) {
    name = String(name === undefined ? "" : name).trim();
    type = String(type === undefined ? "" : type).trim();
    if (!name) throw new Error("author.Task(name, type): name is required");
    if (!type) throw new Error("author.Task(name, type): type is required");
    const task = {
        uuid: crypto.randomUUID(), name, type, priority: 50, commands: [], dependencies: [],
        addCommand(command) {
            if (!command || typeof command.name !== "string") {
                throw new Error(`task ${name}: addCommand needs an author.Command`);
            }
            this.commands.push(command);
        },
        addDependency(dependency) {
            if (!dependency || typeof dependency.uuid !== "string") {
                throw new Error(`task ${name}: addDependency needs an author.Task`);
            }
            this.dependencies.push(dependency);
        },
    };
    return task;
}

const author = {
    Task: makeTask,
    Command(name, parameters, totalStepCount) {
        return { name, parameters: parameters || {}, totalStepCount: totalStepCount || 0 };
    },
};

// Flamenco's `path` module works on slash paths whatever the platform (crosspath).
const path = {
    join: (...parts) => nodePath.posix.join(...parts),
    dirname: (p) => nodePath.posix.dirname(p),
    basename: (p) => nodePath.posix.basename(p),
    stem: (p) => nodePath.posix.basename(p, nodePath.posix.extname(p)),
};

function makeJob(name, settings) {
    const job = {
        name, settings, metadata: {}, created: new Date(0), priority: 50, tasks: [],
        addTask(task) {
            // A copy, as Go's AddTask: later changes to `task` do not reach the job.
            this.tasks.push({ ...task, commands: [...task.commands],
                              dependencies: [...task.dependencies] });
        },
    };
    return job;
}

function load(scriptPath) {
    const printed = [];
    const context = vm.createContext({
        author, path, print: (...args) => printed.push(args.join(" ")),
        formatTimestampLocal: (date) => new Date(date).toISOString().replace(/[:T]/g, "-").slice(0, 19),
    });
    vm.runInContext(fs.readFileSync(scriptPath, "utf8") + "\n;this.JOB_TYPE = JOB_TYPE;",
                    context, { filename: scriptPath });
    if (typeof context.compileJob !== "function") throw new Error("no compileJob(job) function");
    checkJobType(context.JOB_TYPE);
    return { context, printed };
}

const SETTING_TYPES = new Set(["string", "int32", "float", "bool"]);

function checkJobType(jobType) {
    if (!jobType || typeof jobType.label !== "string" || !Array.isArray(jobType.settings)) {
        throw new Error("JOB_TYPE needs a label and a list of settings");
    }
    const keys = new Set();
    for (const setting of jobType.settings) {
        if (!setting.key || keys.has(setting.key)) throw new Error(`bad or repeated key ${setting.key}`);
        if (!SETTING_TYPES.has(setting.type)) throw new Error(`${setting.key}: unknown type ${setting.type}`);
        if (setting.choices && setting.default !== undefined && !setting.choices.includes(setting.default)) {
            throw new Error(`${setting.key}: default not among its choices`);
        }
        keys.add(setting.key);
    }
}

// Run the script's compileJob on `settings` (defaults filled in, required ones checked).
function compile(scriptPath, settings, name = "bake job") {
    const { context, printed } = load(scriptPath);
    const filled = {};
    for (const setting of context.JOB_TYPE.settings) {
        if (settings[setting.key] !== undefined) filled[setting.key] = settings[setting.key];
        else if (setting.default !== undefined) filled[setting.key] = setting.default;
        else if (setting.required && !setting.eval) {
            throw new Error(`required setting ${setting.key} missing`);
        }
    }
    for (const key of Object.keys(settings)) {
        if (!(key in filled)) filled[key] = settings[key];
    }
    const job = makeJob(name, filled);
    context.compileJob(job);
    checkJob(job);
    return { job, printed };
}

function checkJob(job) {
    const byUuid = new Map(job.tasks.map((t) => [t.uuid, t]));
    const names = new Set();
    for (const task of job.tasks) {
        if (names.has(task.name)) throw new Error(`task name ${task.name} used twice`);
        names.add(task.name);
        for (const dep of task.dependencies) {
            if (!byUuid.has(dep.uuid)) throw new Error(`${task.name} depends on a task not in the job`);
        }
    }
    const state = new Map();  // uuid -> "visiting" | "done"
    const visit = (task) => {
        if (state.get(task.uuid) === "done") return;
        if (state.get(task.uuid) === "visiting") throw new Error(`dependency cycle at ${task.name}`);
        state.set(task.uuid, "visiting");
        for (const dep of task.dependencies) visit(byUuid.get(dep.uuid));
        state.set(task.uuid, "done");
    };
    job.tasks.forEach(visit);
}

module.exports = { author, path, compile, load, checkJob, makeJob };
