"""For scripts/ui_screenshot: Blender with its UI (under Xvfb), the add-on enabled, the phantom imported,
skeletonized and rigged through the add-on's operators, the volrig panels on the sidebar's first tab. Prints
"UI READY" when the screen is ready for a screenshot. UI_MESH=1: the shared knight mesh instead, rigged by Rig Mesh,
its left elbow bent and that forearm made thicker, in pose mode with the forearm selected (its thickness slider);
UI_MESH=<path under the data root>: that mesh, rigged.
UI_BAKE=1: every volrig panel closed but Bake. UI_CAPSULES=<pose>: a capsule humanoid
(volrig_support.subjects.capsule_subject, e.g. wide; "bird": capsule_bird_subject) instead of the phantom.
UI_MARKERS=1: four markers placed before Rig (the Markers box lists the missing ones); with UI_MESH, the character's
five reference markers (benchmarks/rig_characters.py) before Rig Mesh."""
import os, sys
REPO = os.environ.get("REPO", os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
WORK = os.environ.get("UI_WORK", "/tmp")
sys.path[:0] = [os.path.join(REPO, "python"), os.path.join(REPO, "addon"), os.path.join(REPO, "tests", "support")]
import bpy
from mathutils import Vector
import volrig, volrig_addon
from volrig_support import data_root
import inspect
_panels = [c for m in volrig_addon.FEATURES for c in vars(m).values()
           if inspect.isclass(c) and issubclass(c, bpy.types.Panel) and getattr(c, "bl_category", "") == "volrig"]
for c in _panels:
    c.bl_category = "Item"  # for the screenshot only: the sidebar opens on its first tab
    if (os.environ.get("UI_LOOKS") or os.environ.get("UI_TISSUES") or os.environ.get("UI_VHM")) and c.__name__ in ("VOLRIG_PT_volume", "VOLRIG_PT_segment", "VOLRIG_PT_skeleton"):
        c.bl_options = {"DEFAULT_CLOSED"}  # room for the Parts panel
    if os.environ.get("UI_BAKE") and c.__name__ not in ("VOLRIG_PT_bake",):
        c.bl_options = {"DEFAULT_CLOSED"}  # room for the Bake panel
volrig_addon.register()

def key_bone(vol, name, axis, keys, end):
    """Keys pose bone ``name`` of the volume's rig turned about its local ``axis`` (0, 1, 2) by (frame, radians)
    ``keys``; the scene runs from frame 1 to ``end``."""
    from mathutils import Euler
    from volrig_addon.objects import members
    scene = bpy.context.scene
    scene.frame_start, scene.frame_end = 1, end
    pb = members(vol)["RIG"].pose.bones[name]
    pb.rotation_mode = "XYZ"
    for frame, angle in keys:
        pb.rotation_euler = Euler(tuple(angle if a == axis else 0.0 for a in range(3)))
        pb.keyframe_insert("rotation_euler", frame=frame)


def contacts(vol):
    key_bone(vol, "forearm.R", 2, ((1, 0.0), (20, -0.8), (40, 0.0)), 40)
    print("find_contacts:", bpy.ops.volrig.find_contacts(), flush=True)
    bpy.context.scene.frame_set(20)


def markers(vol):
    """UI_MARKERS=1: four of the asked-for markers placed (at the phantom's joints), groin and right knee missing."""
    joints = volrig.phantom.humanoid(0.4).joints
    mid = 0.5 * (joints["shoulder.L"] + joints["shoulder.R"]) + [0, 0, 20]
    for name, p in (("chin", mid), ("wrist.L", joints["wrist.L"]), ("wrist.R", joints["wrist.R"]),
                    ("knee.L", joints["knee.L"])):
        vol.volrig.marker_name = name
        bpy.ops.volrig.place_marker(location=tuple(vol.matrix_world @ Vector(tuple(map(float, p)))))


def reference_markers_on(obj, path):
    """UI_MARKERS=1 with UI_MESH: the five markers benchmarks/rig_characters.py takes from the character's reference
    skeleton (chin, wrists, groin, left knee), placed on the mesh object before Rig Mesh (file +Y turned to +Z)."""
    sys.path.insert(0, os.path.join(REPO, "benchmarks"))
    from rig_characters import reference_markers
    from volrig_support import characters
    sub = characters.characters([os.path.basename(path).rsplit(".", 1)[0]])[0]
    for name, p in reference_markers(*sub.reference, sub.up).items():
        obj.volrig.marker_name = name
        bpy.ops.volrig.place_marker(location=(float(p[0]), -float(p[2]), float(p[1])))


def live_preview(vol):
    """The left forearm keyed from straight (frame 1) to bent (frame 20); frame 20 is not baked: the preview."""
    from volrig_addon.objects import members
    key_bone(vol, "forearm.L", 0, ((1, 0.0), (20, 1.4)), 40)
    members(vol)["SPHERES"].hide_set(True)
    bpy.context.scene.frame_set(20)


def knight_scene(mesh: str = "1"):
    """The shared knight (+Y up in the file: turned to +Z) rigged by Rig Mesh, the left elbow bent 90 degrees and
    the left forearm 1.6 times as thick, in pose mode with the forearm active. ``mesh``: another mesh under the data
    root (UI_MESH=characters/axl/....obj), +Y up in its file as the add-on's importers take it, rigged and left so."""
    import math
    import numpy as np
    path = "meshes/decimated-knight.off" if mesh == "1" else mesh
    v, f = volrig.read_mesh(str(data_root() / path))
    v = np.asarray(v, float)
    from volrig_addon import mesh_rig
    name = os.path.basename(path).split(".")[0][:20]
    mesh_rig.new_mesh_object(bpy.context, name, np.stack([v[:, 0], -v[:, 2], v[:, 1]], axis=1), f, smooth=True)
    if os.environ.get("UI_MARKERS") and mesh != "1":
        reference_markers_on(bpy.context.active_object, path)
    print("rig_mesh:", bpy.ops.volrig.rig_mesh(), flush=True)
    arm = bpy.context.active_object
    if mesh != "1":
        return
    bpy.ops.object.mode_set(mode="POSE")
    pb = arm.pose.bones["forearm.L"]
    pb.rotation_mode = "XYZ"
    pb.rotation_euler = (math.radians(-90.0), 0.0, 0.0)  # forwards (the knight faces -Y)
    pb["volrig_thickness"] = 1.6
    arm.data.bones.active = arm.data.bones["forearm.L"]
    arm.data.bones["forearm.L"].select = True
    arm.update_tag()


def setup():
    if os.environ.get("UI_MESH"):
        return setup_mesh()
    if os.environ.get("UI_VHM"):
        return setup_vhm()
    pose = os.environ.get("UI_CAPSULES")  # a capsule humanoid in this pose (volrig_support.subjects.CAPSULE_POSES)
    name = "capsules" if pose else "phantom"
    path = os.path.join(WORK, f"{name}.nrrd")
    if not os.path.exists(path):
        if pose:
            from volrig_support.subjects import capsule_bird_subject, capsule_subject
            subject = capsule_bird_subject(1.0) if pose == "bird" else capsule_subject(pose, 1.0)
            volrig.Volume(subject.mask.array.astype("uint8") * 255).save(path)
        else:
            volrig.phantom.humanoid(0.4).volume.save(path)
    win, override = empty_view3d()
    with override:
        bpy.ops.wm.save_as_mainfile(filepath=os.path.join(WORK, "scene.blend"))
        bpy.ops.volrig.import_volume(filepath=path, unit="MM", name=name)
        vol = bpy.data.objects[name]
        bpy.context.view_layer.objects.active = vol
        vol.select_set(True)
        bpy.ops.volrig.skeletonize()
        vol.volrig.thinness = 0.25
        if os.environ.get("UI_MARKERS") and not pose:  # chin, wrists and the left knee marked before Rig
            markers(vol)
        bpy.ops.volrig.rig()
        bpy.context.view_layer.objects.active = vol
        vol.select_set(True)
        if os.environ.get("UI_CONTACTS"):  # key the right arm swung through the body, then Find Contacts
            contacts(vol)
        if os.environ.get("UI_PREVIEW"):
            live_preview(vol)
        if os.environ.get("UI_THICKNESS"):  # the bone's thickness as colour, the scan and the rig hidden
            vol.volrig.low, vol.volrig.high, vol.volrig.largest = 150, 255, False
            print("show_thickness:", bpy.ops.volrig.show_thickness(), flush=True)
            from volrig_addon.objects import members
            for role, o in members(vol).items():
                o.hide_set(role != "THICKNESS")
            vol.hide_set(True)
        if os.environ.get("UI_LOOKS"):  # the Parts list: the left arm red, the right leg hidden, the rest translucent
            s = vol.volrig
            s.preset, s.density_scale = "GREY", 0.3
            s.use_parts = True
            for p in s.parts:
                p.colored, p.opacity = p.name == "left arm", 2.0 if p.name == "left arm" else 0.1
                p.visible = p.name != "right leg"
            _part = [p for p in s.parts if p.name == "left arm"][0]
            _part.color = (1.0, 0.05, 0.02)
            from volrig_addon import staging
            scene = bpy.context.scene
            staging.stage(scene, vol, samples=8).hide_set(True)  # a sun, a dim world, Cycles; the camera out of view
            scene.cycles.preview_samples, scene.cycles.use_preview_denoising = 8, False
            s.parts_index = [p.name for p in s.parts].index("left arm")
        if os.environ.get("UI_TISSUES"):  # the Tissues list from a table: bone white, muscle red, fat hidden
            table = os.path.join(WORK, "phantom_tissues.tsv")
            with open(table, "w") as f:
                f.write("code\tname\n80\tMuscle\n100\tFat\n220\tBoneCortical\n")
            s = vol.volrig
            s.tissue_table, s.use_tissues, s.density_scale = table, True, 0.5
            for t in s.tissues:
                t.visible = t.name != "fat"
            from volrig_addon import staging
            scene = bpy.context.scene
            staging.stage(scene, vol, samples=8).hide_set(True)
            scene.cycles.preview_samples, scene.cycles.use_preview_denoising = 8, False
            from volrig_addon.objects import members
            for role, o in members(vol).items():
                o.hide_set(True)
        if os.environ.get("UI_MEDIAL"):  # the body's medial surface and rods, the scan and the rig hidden
            print("medial_surface:", bpy.ops.volrig.medial_surface(), flush=True)
            from volrig_addon.objects import members
            for role, o in members(vol).items():
                o.hide_set(role != "MEDIAL")
            vol.hide_set(True)
    return show_volrig_sidebar(win, "MATERIAL" if os.environ.get("UI_THICKNESS") or os.environ.get("UI_MEDIAL")
                               else "RENDERED" if os.environ.get("UI_TISSUES") else "SOLID")


def show_volrig_sidebar(win, shading, three_quarter=False):
    """The 3D view with its sidebar on the volrig panels, ``shading``, from the front (or a three-quarter view from
    above the front left), everything in view; then "UI READY"."""
    for area in win.screen.areas:
        if area.type == "VIEW_3D":
            for space in area.spaces:
                if space.type == "VIEW_3D":
                    space.show_region_ui = True
                    space.shading.type = shading
            for region in area.regions:
                if region.type == "UI":
                    try:
                        region.active_panel_category = "volrig"
                    except Exception as e:
                        print("category:", e)
            with bpy.context.temp_override(window=win, area=area, region=[r for r in area.regions if r.type == "WINDOW"][0]):
                bpy.ops.view3d.view_axis(type="FRONT")
                if three_quarter:  # the bent elbow seen from the side
                    bpy.ops.view3d.view_orbit(angle=0.7, type="ORBITLEFT")
                    bpy.ops.view3d.view_orbit(angle=0.25, type="ORBITUP")
                bpy.ops.view3d.view_all()
                if os.environ.get("UI_MARKERS"):  # the selected volume (and its markers) filling the view
                    bpy.ops.view3d.view_selected()
    bpy.ops.wm.redraw_timer(type="DRAW_WIN_SWAP", iterations=1)
    print("UI READY", flush=True)
    return None


def setup_vhm():
    """UI_VHM=1: the Visible Human's 4 mm labels imported (its tissue table found beside it: per-tissue looks on),
    rendered in the viewport from the front with fat and muscle hidden."""
    path = str(data_root() / "visible-human" / "austinman_4mm_labels.nii.gz")
    win, override = empty_view3d()
    with override:
        bpy.ops.wm.save_as_mainfile(filepath=os.path.join(WORK, "scene.blend"))
        print("import:", bpy.ops.volrig.import_volume(filepath=os.path.normpath(path), unit="MM", name="vhm"), flush=True)
        vol = bpy.data.objects["vhm"]
        s = vol.volrig
        s.density_scale = 0.5
        for t in s.tissues:
            t.visible = t.name not in ("fat", "muscle", "skin", "cartilage")
        if os.environ.get("UI_VHM_RIG"):  # rigged (Rigid tissue: Automatic, the table's bone), the left knee bent
            vhm_knee(vol)
        from volrig_addon import staging
        scene = bpy.context.scene
        staging.stage(scene, vol, samples=8).hide_set(True)
        scene.cycles.preview_samples, scene.cycles.use_preview_denoising = 8, False
    return show_volrig_sidebar(win, "RENDERED")


def vhm_knee(vol):
    """UI_VHM_RIG=1: skeletonized, rigged (the table's bone as rigid tissue, by Automatic), the left knee keyed
    from straight (frame 1) to bent UI_KNEE degrees (default 90; frame 10), shown at frame 10 unbaked: the live
    preview."""
    import math
    from volrig_addon.objects import members
    bpy.context.view_layer.objects.active = vol
    vol.select_set(True)
    print("skeletonize:", bpy.ops.volrig.skeletonize(), flush=True)
    print("rig:", bpy.ops.volrig.rig(), flush=True)
    key_bone(vol, "shin.L", 0, ((1, 0.0), (10, math.radians(float(os.environ.get("UI_KNEE", "90"))))), 10)
    members(vol)["SPHERES"].hide_set(True)
    bpy.context.scene.frame_set(10)


def empty_view3d():
    """Removes every object; returns (the window, a context override on its 3D view)."""
    win = bpy.context.window_manager.windows[0]
    area = [a for a in win.screen.areas if a.type == "VIEW_3D"][0]
    region = [r for r in area.regions if r.type == "WINDOW"][0]
    for o in list(bpy.data.objects):
        bpy.data.objects.remove(o)
    return win, bpy.context.temp_override(window=win, area=area, region=region)


def setup_mesh():
    win, override = empty_view3d()
    with override:
        knight_scene(os.environ["UI_MESH"])
    return show_volrig_sidebar(win, "SOLID", three_quarter=True)


bpy.app.timers.register(setup, first_interval=1.0)
