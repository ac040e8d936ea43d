"""The Rig panel's Markers step (issue 53): markers placed on the volume steer the rig's body plan and sit on
their joints, are saved with the .blend, and clear; the panel says which are missing."""
import os

import numpy as np
import pytest

from conftest import bpy, run_op

import volrig


def _world(vol, p):
    from mathutils import Vector
    return tuple(vol.matrix_world @ Vector(tuple(float(x) for x in p)))


def test_markers_place_the_joints_and_save_with_the_blend(rigged, phantom_file, tmp_path):
    from volrig_addon import markers
    vol = rigged
    ph = phantom_file[1]
    assert markers.missing(vol) == list(markers.ASKED) and vol.volrig.marker_name == "chin"
    # wrists marked the other way round than the phantom's own sides: the rig's names follow the markers
    for name, joint in (("wrist.L", "wrist.R"), ("wrist.R", "wrist.L"), ("knee.L", "knee.L")):
        vol.volrig.marker_name = name
        run_op(bpy.ops.volrig.place_marker, location=_world(vol, ph.joints[joint]))
    assert set(markers.markers_of(vol)) == {"wrist.L", "wrist.R", "knee.L"}
    assert vol.volrig.marker_name == "chin"  # the next missing one is picked
    np.testing.assert_allclose(markers.marker_points(vol)["wrist.L"], ph.joints["wrist.R"], atol=1e-4)
    run_op(bpy.ops.volrig.rig)
    saved = volrig.load_rig(os.path.join(bpy.path.abspath(vol.volrig.cache_dir), vol.volrig.rig_file))
    assert saved.rig.kind == "humanoid"
    hand_l = saved.rig.heads()[saved.rig.names.index("hand.L")]
    np.testing.assert_allclose(hand_l, ph.joints["wrist.R"], atol=1e-3)
    # saved with the .blend, moved with the volume
    name, path = vol.name, str(tmp_path / "markers.blend")
    bpy.ops.wm.save_as_mainfile(filepath=path)
    bpy.ops.wm.open_mainfile(filepath=path)
    vol = bpy.data.objects[name]
    assert set(markers.markers_of(vol)) == {"wrist.L", "wrist.R", "knee.L"}
    bpy.context.view_layer.objects.active = vol
    run_op(bpy.ops.volrig.clear_markers, name="knee.L")
    assert set(markers.markers_of(vol)) == {"wrist.L", "wrist.R"}
    run_op(bpy.ops.volrig.clear_markers)
    assert markers.markers_of(vol) == {}


def test_unknown_marker_names_are_refused(rigged):
    from volrig_addon import markers
    with pytest.raises(volrig.VolrigError, match="unknown marker"):
        markers.place(rigged, "elbow", (0, 0, 0))


def test_clicks_count_over_the_view_only():
    """The modal Place starts from the sidebar's button: a click counts over the view itself, in its coordinates,
    not over the sidebar or the header that overlap it."""
    from types import SimpleNamespace as NS
    from volrig_addon.markers import _view
    view = NS(type="WINDOW", x=100, y=50, width=800, height=600)
    area = NS(regions=[view, NS(type="UI", x=650, y=50, width=250, height=600),
                       NS(type="HEADER", x=100, y=626, width=800, height=24)])
    region, xy = _view(area, NS(mouse_x=300, mouse_y=250))
    assert region is view and xy == (200, 200)
    assert _view(area, NS(mouse_x=700, mouse_y=250)) is None  # the sidebar
    assert _view(area, NS(mouse_x=300, mouse_y=640)) is None  # the header
    assert _view(area, NS(mouse_x=50, mouse_y=250)) is None  # outside the area
