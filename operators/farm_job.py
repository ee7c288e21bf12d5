"""windgrass.farm_job: write a render-farm job bundle for the saved file (Open Job Description,
Flamenco); the bundle's README line says how to run or submit it."""

from pathlib import Path

import bpy

from ..grass_addon.bridge.runtime import farm_job
from ._common import reported


class WINDGRASS_OT_farm_job(bpy.types.Operator):
    """Write a render-farm job for the saved file: its frames in chunks, for any Blender on the farm"""

    bl_idname = "windgrass.farm_job"
    bl_label = "Farm Job..."
    bl_description = ("Write a job bundle that renders the saved file's frames on a render farm (Open Job "
                      "Description: openjd run, AWS Deadline Cloud; a Flamenco job type), carrying the Windgrass "
                      "extension for workers that have none")
    bl_options = {"REGISTER", "UNDO"}  # (writes files only; the rule for every operator here)

    directory: bpy.props.StringProperty(name="Bundle Folder", subtype="DIR_PATH",
                                        description="Where the job bundle is written")
    chunk_size: bpy.props.IntProperty(name="Frames per Task", default=4, min=1, soft_max=100,
                                      description="How many frames a task renders on the farm")
    allow_outside: bpy.props.BoolProperty(
        name="Allow Outside Files", default=False,
        description="Name the files the .blend uses from outside its folder for the farm to upload too (off: "
                    "refused, each named; the bundle carries only the .blend's own files)")
    hand_over: bpy.props.EnumProperty(
        name="Hand-over", default="blender",
        items=[("blender", "Blender", "A small Blender hands each task to the worker session's Blender: any worker, "
                "about a second a task"),
               ("python3", "Python 3", "The workers' python3 hands each task over: milliseconds a task (Linux and "
                "macOS workers with Python 3.8+)")],
        description="What hands each task's frames to the one Blender that a worker's session keeps")

    @classmethod
    def poll(cls, context):
        return context.scene is not None

    def invoke(self, context, event):
        if not self.directory and bpy.data.filepath:
            blend = Path(bpy.data.filepath)
            self.directory = str(blend.with_name(blend.stem + "_farm_job")) + "/"
        context.window_manager.fileselect_add(self)
        return {"RUNNING_MODAL"}

    @reported
    def execute(self, context):
        if not self.directory:
            self.report({"ERROR"}, "Choose the folder the job bundle is written to")
            return {"CANCELLED"}
        folder = Path(bpy.path.abspath(self.directory))
        if bpy.data.filepath and folder.resolve() == Path(bpy.data.filepath).resolve().parent:
            # the file browser falls back to the .blend's folder when the suggested one does not exist
            # yet: the bundle (a dozen files and folders) goes into a folder of its own there
            folder = folder / (Path(bpy.data.filepath).stem + "_farm_job")
        folder, elsewhere = farm_job.write_blend_bundle(context.scene, folder, self.chunk_size,
                                                        hand_over=self.hand_over, allow_outside=self.allow_outside)
        self.report({"INFO"}, f"Farm job written to {folder}: openjd run {folder / 'template.yaml'} --job-param "
                              f"file://{folder / 'job_params.yaml'} --step Render, or deadline bundle submit "
                              f"{folder} --yes (the frames come back into its output/)")
        if elsewhere:
            more = " ..." if len(elsewhere) > 3 else ""
            self.report({"WARNING"}, f"The file uses {len(elsewhere)} file(s) from outside its folder, not carried in "
                                     f"the bundle (Deadline Cloud asks before attaching them; a farm's shared storage "
                                     f"must hold them): {', '.join(elsewhere[:3])}{more}")
        return {"FINISHED"}


CLASSES = (WINDGRASS_OT_farm_job,)
