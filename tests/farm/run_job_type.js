// Compiles a Flamenco job type against a small stand-in of Flamenco's job-compiler API (the globals the Manager
// gives a job type: author.Task, author.Command, task.addCommand / addDependency, job.addTask, print, path) and
// prints the job it authored as JSON:
//
//   node tests/farm/run_job_type.js farm/flamenco/volrig_bake_render.js '{"blendfile": "/s/a.blend", ...}'
//
// Output: {"job_type": {label, settings keys}, "tasks": [{name, type, commands: [{name, parameters}],
// dependencies: [names]}]}, or {"error": "..."} with exit status 3 when compileJob throws.
"use strict";
const fs = require("fs");
const nodePath = require("path");
const vm = require("vm");

const [file, settingsJson] = process.argv.slice(2);
const tasks = [];

class Task {
    constructor(name, type) {
        if (typeof name !== "string" || !name) throw new Error("author.Task: a name is required");
        this.name = name;
        this.type = type;
        this.commands = [];
        this.dependencies = [];
    }
    addCommand(cmd) {
        if (!(cmd instanceof Command)) throw new Error(`${this.name}: addCommand takes an author.Command`);
        this.commands.push(cmd);
    }
    addDependency(task) {
        if (!(task instanceof Task)) throw new Error(`${this.name}: addDependency takes an author.Task`);
        this.dependencies.push(task);
    }
}

class Command {
    constructor(name, parameters) {
        this.name = name;
        this.parameters = parameters;
    }
}

const job = {
    name: "test job",
    created: new Date(0),
    settings: JSON.parse(settingsJson || "{}"),
    addTask(task) {
        if (!(task instanceof Task)) throw new Error("job.addTask takes an author.Task");
        if (tasks.some((t) => t.name === task.name)) throw new Error(`two tasks named ${task.name}`);
        for (const d of task.dependencies) {
            if (!tasks.includes(d)) throw new Error(`${task.name} depends on ${d.name}, which is not in the job yet`);
        }
        tasks.push(task);
    },
};

const context = {
    author: { Task: (name, type) => new Task(name, type), Command: (name, params) => new Command(name, params) },
    print: (...args) => process.stderr.write(args.map(String).join(" ") + "\n"),
    path: {
        join: nodePath.posix.join, basename: nodePath.posix.basename, dirname: nodePath.posix.dirname,
        stem: (p) => nodePath.posix.basename(p, nodePath.posix.extname(p)),
    },
};
vm.createContext(context);
// Flamenco evaluates the file as a script: JOB_TYPE and compileJob are top-level declarations.
vm.runInContext(fs.readFileSync(file, "utf8") + "\n;this.__jobType = JOB_TYPE; this.__compile = compileJob;",
                context, { filename: file });
const jobType = context.__jobType;
for (const s of jobType.settings) {  // Flamenco fills in defaults for settings not given
    if (!(s.key in job.settings) && "default" in s) job.settings[s.key] = s.default;
}
const out = { job_type: { label: jobType.label, settings: jobType.settings.map((s) => s.key) } };
try {
    context.__compile(job);
} catch (e) {
    out.error = String(e && e.message ? e.message : e);
    process.stdout.write(JSON.stringify(out) + "\n");
    process.exit(3);
}
out.tasks = tasks.map((t) => ({
    name: t.name, type: t.type,
    commands: t.commands.map((c) => ({ name: c.name, parameters: c.parameters })),
    dependencies: t.dependencies.map((d) => d.name),
}));
process.stdout.write(JSON.stringify(out, null, 1) + "\n");
