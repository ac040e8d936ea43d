"""docs/centerline.md's fly-through picture: the airway of ../shared/data/airway flown through by the add-on's Fly
Through (as ``volrig flythrough`` builds it) and frame 75 (the carina) rendered in Cycles at 200 x 200, 64 samples.

    blender -b --factory-startup --python scripts/flythrough_picture.py

Writes docs/images/flythrough_airway.png (the .blend and its cache go to a temporary folder)."""
import os
import shutil
import sys
import tempfile

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path[:0] = [os.path.join(REPO, "python"), os.path.join(REPO, "addon"), os.path.join(REPO, "tests", "support")]

import bpy  # noqa: E402
import volrig_addon  # noqa: E402

volrig_addon.register()
from volrig_addon import flythrough  # noqa: E402
from volrig_support import data_root  # noqa: E402

AIRWAY = str(data_root() / "airway" / "Patient1_bronchialTree.nii.gz")
FRAME, SIZE, SAMPLES = 75, 200, 64
work = tempfile.mkdtemp(prefix="volrig_fly_")
try:
    flythrough.build_from_file({"file": AIRWAY, "lo": 1, "output": os.path.join(work, "air.blend"),
                                "frames_per_mm": 1.0})
    scene = bpy.context.scene
    r = scene.render
    r.resolution_x = r.resolution_y = SIZE
    r.resolution_percentage = 100
    r.image_settings.file_format = "PNG"
    scene.cycles.samples = SAMPLES
    scene.cycles.use_denoising = False
    scene.frame_set(FRAME)
    r.filepath = os.path.join(REPO, "docs", "images", "flythrough_airway.png")
    bpy.ops.render.render(write_still=True)
finally:
    shutil.rmtree(work, ignore_errors=True)
sys.stdout.flush()
os._exit(0)
