"""Fixtures for tests that run inside headless Blender (see run.py): the add-on registered once, a factory-fresh
scene per test, and the humanoid phantom imported, skeletonized and rigged through the operators."""

import pytest

bpy = pytest.importorskip("bpy", reason="these tests run inside Blender: see tests/blender/run.py")

PHANTOM_SCALE = 0.35


@pytest.fixture(scope="session", autouse=True)
def addon():
    import volrig_addon
    volrig_addon.register()
    yield volrig_addon
    volrig_addon.unregister()


@pytest.fixture
def empty_scene(tmp_path, monkeypatch):
    bpy.ops.wm.read_homefile(use_empty=True, use_factory_startup=True)
    monkeypatch.setattr("tempfile.tempdir", str(tmp_path))  # unsaved files cache under the test's folder
    return bpy.context.scene


@pytest.fixture(scope="session")
def phantom_file(tmp_path_factory):
    import volrig
    ph = volrig.phantom.humanoid(scale=PHANTOM_SCALE)
    path = tmp_path_factory.mktemp("phantom") / "phantom.nrrd"
    ph.volume.save(str(path))
    return str(path), ph


def run_op(op, **kw):
    """Runs an operator and fails the test with its reports when it does not finish."""
    result = op(**kw)
    assert result == {"FINISHED"}, f"{op.idname()} returned {result}"
    return result


def import_and_rig(path):
    """Imports a volume file in mm, skeletonizes it at thinness 0.3 and rigs it; returns the Volume object."""
    run_op(bpy.ops.volrig.import_volume, filepath=path, unit="MM")
    vol = bpy.context.active_object
    vol.volrig.low = 1.0
    run_op(bpy.ops.volrig.skeletonize)
    vol.volrig.thinness = 0.3
    run_op(bpy.ops.volrig.rig)
    return vol


@pytest.fixture
def rigged(empty_scene, phantom_file):
    """The phantom imported, skeletonized at thinness 0.3 and rigged; returns the Volume object."""
    return import_and_rig(phantom_file[0])
