// Windgrass job type for Flamenco: put this file in the scripts/ folder beside the Flamenco
// Manager (Flamenco's docs: "Job Types"); it shows up as "Windgrass" in Flamenco's add-on.
//
// Two kinds of job, chunked like Flamenco's own "Simple Blender Render":
//   scene_file  a Windgrass scene file (TOML): each task runs
//               {blender} -b -P <windgrass_dir>/headless/render_field.py -- --config SCENE
//                   --frames CHUNK --out DIR --resume    (CHUNK: "1-4", "5,6" or "9,10,20,21")
//   blend       a saved .blend with live grass: each task runs the .blend with farm_render.py,
//               which installs the extension zip when the worker's Blender has none
// Every written frame prints Blender's "Saved: '<path>'" line; frames already complete on disk
// are skipped, so a requeued task renders only what is missing.

const JOB_TYPE = {
  label: "Windgrass",
  description: "Render Windgrass grass fields in chunks of frames (a scene file or a saved .blend)",
  settings: [
    { key: "kind", type: "string", choices: ["blend", "scene_file"], default: "blend", required: true,
      description: "What is rendered: a saved .blend with live grass, or a Windgrass scene file" },
    { key: "blendfile", type: "string", description: "The saved .blend (kind blend)", visible: "web" },
    { key: "scene_file", type: "string", subtype: "file_path", description: "The scene file (kind scene_file)" },
    { key: "windgrass_dir", type: "string", subtype: "dir_path", required: true,
      description: "Folder of the Windgrass job files: the scripts (headless/), farm_render.py, the extension zip" },
    { key: "extension_zip", type: "string", subtype: "file_path", description: "The Windgrass extension zip (kind blend)" },
    { key: "version", type: "string", description: "The Windgrass version the job was made with (kind blend)" },
    { key: "frames", type: "string", required: true, eval: "f'{C.scene.frame_start}-{C.scene.frame_end}'",
      description: "Frames to render: 'A-B' or a list of them ('1-10,20-30'); each task gets its chunk as Flamenco writes it ('5,6', '9,10,20,21'), which the scripts read" },
    { key: "chunk_size", type: "int32", default: 4, description: "Frames a task renders in one Blender" },
    { key: "render_output_root", type: "string", subtype: "dir_path", required: true,
      description: "Folder the frames are written to (frame_NNNN.png)" },
  ],
};

function compileJob(job) {
  const settings = job.settings;
  if (!(settings.chunk_size >= 1)) {
    throw `chunk_size is ${settings.chunk_size}; valid: a whole number of frames, at least 1`;
  }
  if (settings.kind !== "blend" && settings.kind !== "scene_file") {
    throw `kind is ${JSON.stringify(settings.kind)}; valid: "blend" or "scene_file"`;
  }
  if (settings.kind === "scene_file" && !settings.scene_file) {
    throw "a scene_file job needs the scene file (scene_file)";
  }
  if (settings.kind === "blend" && !settings.blendfile) {
    throw "a blend job needs the saved .blend (blendfile)";
  }
  for (const chunk of frameChunker(settings.frames, settings.chunk_size)) {
    const task = author.Task(`render-${chunk}`, "blender");
    task.addCommand(renderCommand(settings, chunk));
    job.addTask(task);
  }
}

function renderCommand(settings, chunk) {
  const out = settings.render_output_root;
  if (settings.kind === "scene_file") {
    return author.Command("exec", {
      exe: "{blender}",
      args: ["-b", "-P", path.join(settings.windgrass_dir, "headless", "render_field.py"), "--",
             "--config", settings.scene_file, "--frames", chunk, "--out", out, "--resume"],
    });
  }
  const args = ["--python", path.join(settings.windgrass_dir, "farm_render.py"), "--",
                "--frames", chunk, "--out", out];
  if (settings.version) args.push("--version", settings.version);
  if (settings.extension_zip) args.push("--extension", settings.extension_zip);
  return author.Command("blender-render", {
    exe: "{blender}",
    exeArgs: "{blenderArgs}",
    argsBefore: [],
    blendfile: settings.blendfile,
    args: args,
  });
}
