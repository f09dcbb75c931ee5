"""The on-disk cache of decimated preview meshes (ipromp_pin.preview.mesh_cache, ipromp_pin.cache)."""

from __future__ import annotations

import json
import os
import shutil
import stat

import coal
import numpy as np
import pinocchio as pin
import pytest

from ipromp_pin import cache
from ipromp_pin.preview import DEFAULT_MAX_TRIANGLES, count_triangles, simplify_visual_model
from ipromp_pin.preview.mesh_cache import cached_visual_model, visual_model_key
from ipromp_pin.robot import load_robot, load_visual_model


@pytest.fixture(scope="module")
def baxter():
    robot = load_robot("baxter_left")
    return robot, load_visual_model(robot)


def cached(robot, visual, folder, loads):
    s = robot.settings

    def load():
        loads.append(1)
        return visual

    urdf, dirs = s.urdf_path, s.package_dirs
    return cached_visual_model(robot.model, urdf, dirs, DEFAULT_MAX_TRIANGLES, load, folder=folder)


def assert_same_geometry(a: pin.GeometryModel, b: pin.GeometryModel) -> None:
    assert a.ngeoms == b.ngeoms
    for x, y in zip(a.geometryObjects, b.geometryObjects, strict=True):
        assert (x.name, x.parentJoint, x.parentFrame) == (y.name, y.parentJoint, y.parentFrame)
        assert np.allclose(x.placement.homogeneous, y.placement.homogeneous, atol=0.0)
        assert np.array_equal(x.meshColor, y.meshColor) and x.overrideMaterial == y.overrideMaterial
        assert type(x.geometry) is type(y.geometry)
        if isinstance(x.geometry, coal.BVHModelBase):
            assert np.array_equal(x.geometry.vertices(), y.geometry.vertices())
            assert x.geometry.num_tris == y.geometry.num_tris
            for k in range(0, x.geometry.num_tris, 97):
                a, b = x.geometry.tri_indices(k), y.geometry.tri_indices(k)
                assert (a[0], a[1], a[2]) == (b[0], b[1], b[2])
        else:
            assert np.array_equal(x.geometry.aabb_local.min_, y.geometry.aabb_local.min_)


def test_second_preview_reads_the_decimated_meshes_from_disk(baxter, tmp_path):
    robot, visual = baxter
    loads: list[int] = []
    first = cached(robot, visual, tmp_path, loads)
    assert loads == [1] and len(list(tmp_path.glob("*.npz"))) == 1
    second = cached(robot, visual, tmp_path, loads)
    assert loads == [1]  # not loaded (nor decimated) again
    assert_same_geometry(second, first)
    assert_same_geometry(first, simplify_visual_model(visual))  # the same as without a cache
    assert count_triangles(second) <= 1.05 * DEFAULT_MAX_TRIANGLES
    assert simplify_visual_model(second) is second  # already decimated: used as it is


def test_corrupt_or_stale_entries_are_rebuilt(baxter, tmp_path):
    robot, visual = baxter
    loads: list[int] = []
    reference = cached(robot, visual, tmp_path, loads)
    entry = next(tmp_path.glob("*.npz"))
    entry.write_bytes(entry.read_bytes()[: entry.stat().st_size // 2])  # truncated
    assert_same_geometry(cached(robot, visual, tmp_path, loads), reference)
    assert loads == [1, 1]
    np.savez(entry, objects=np.array("not json"))
    assert_same_geometry(cached(robot, visual, tmp_path, loads), reference)
    assert loads == [1, 1, 1]
    assert_same_geometry(cached(robot, visual, tmp_path, loads), reference)  # rewritten: a hit again
    assert loads == [1, 1, 1]


@pytest.mark.skipif(os.name != "posix" or os.geteuid() == 0, reason="needs a non-root POSIX user")
def test_read_only_cache_folder_only_means_no_cache(baxter, tmp_path):
    robot, visual = baxter
    folder = tmp_path / "ro"
    folder.mkdir()
    folder.chmod(stat.S_IRUSR | stat.S_IXUSR)
    try:
        loads: list[int] = []
        cached(robot, visual, folder, loads)
        cached(robot, visual, folder, loads)
        assert loads == [1, 1] and not list(folder.iterdir())
    finally:
        folder.chmod(stat.S_IRWXU)


def test_unwritable_cache_folder_only_means_no_cache(baxter, tmp_path):
    robot, visual = baxter
    blocker = tmp_path / "file"
    blocker.write_text("a file where the cache folder should be")
    loads: list[int] = []
    model = cached(robot, visual, blocker / "meshes", loads)  # cannot be created
    assert loads == [1] and model.ngeoms == visual.ngeoms
    assert not cache.write_atomically(blocker / "x" / "y.npz", lambda p: p.write_bytes(b"data"))
    assert cache.write_atomically(tmp_path / "ok" / "y.bin", lambda p: p.write_bytes(b"data"))
    assert (tmp_path / "ok" / "y.bin").read_bytes() == b"data" and len(list((tmp_path / "ok").iterdir())) == 1


def test_key_follows_the_content_of_the_description_and_its_meshes(tmp_path):
    mesh = tmp_path / "meshes" / "part.stl"
    mesh.parent.mkdir()
    mesh.write_bytes(b"solid a\nendsolid a\n")
    urdf = tmp_path / "robot.urdf"
    body = (
        '<robot name="r"><link name="base"><visual><geometry><mesh filename="{}"/></geometry></visual>'
        "</link></robot>"
    )
    urdf.write_text(body.format("package://pkg/meshes/part.stl"))
    shutil.copytree(tmp_path / "meshes", tmp_path / "share" / "pkg" / "meshes")
    dirs = [str(tmp_path / "share")]
    key = visual_model_key(urdf, dirs, 1000)
    assert key is not None and key == visual_model_key(urdf, dirs, 1000)
    assert visual_model_key(urdf, dirs, 2000) != key  # another budget
    (tmp_path / "share" / "pkg" / "meshes" / "part.stl").write_bytes(b"solid b\nendsolid b\n")
    assert visual_model_key(urdf, dirs, 1000) != key  # a mesh file changed
    urdf.write_text(body.format("meshes/part.stl"))  # relative to the URDF
    assert visual_model_key(urdf, dirs, 1000) is not None
    urdf.write_text(body.format("package://pkg/meshes/missing.stl"))
    assert visual_model_key(urdf, dirs, 1000) is None  # not cached
    urdf.write_text("<robot")
    assert visual_model_key(urdf, dirs, 1000) is None


def test_cache_folder_follows_the_environment(monkeypatch, tmp_path):
    monkeypatch.setenv(cache.CACHE_ENV, str(tmp_path / "c"))
    assert cache.cache_dir("meshes") == tmp_path / "c" / "meshes"
    monkeypatch.delenv(cache.CACHE_ENV)
    monkeypatch.setattr(cache.sys, "platform", "linux")
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    assert cache.cache_dir() == tmp_path / "xdg" / "ipromp_pin"


def test_unchanged_mesh_files_are_not_read_again(tmp_path):
    mesh = tmp_path / "part.stl"
    mesh.write_bytes(b"solid a\nendsolid a\n")
    urdf = tmp_path / "robot.urdf"
    urdf.write_text(
        '<robot name="r"><link name="base"><visual><geometry><mesh filename="part.stl"/></geometry>'
        "</visual></link></robot>"
    )
    memo = tmp_path / "cache" / "file_digests.json"
    key = visual_model_key(urdf, [], 1000, memo)
    assert key == visual_model_key(urdf, [], 1000)  # the memo changes nothing
    entry = json.loads(memo.read_text())[str(mesh.resolve())]
    assert entry[:2] == [mesh.stat().st_size, mesh.stat().st_mtime_ns]
    # an entry for the file's current size and time is used as it is (the file is not read)
    memo.write_text(json.dumps({str(mesh.resolve()): [*entry[:2], "00" * 32]}))
    assert visual_model_key(urdf, [], 1000, memo) != key
    # a changed file (new size and time) is hashed again; a corrupt memo is ignored
    mesh.write_bytes(b"solid b\nendsolid b\n.")
    other = visual_model_key(urdf, [], 1000, memo)
    assert other not in (None, key) and other == visual_model_key(urdf, [], 1000)
    memo.write_text("{not json")
    assert visual_model_key(urdf, [], 1000, memo) == other


def test_a_first_run_decimates_the_preview_meshes_while_it_trains(tmp_path, monkeypatch):
    from ipromp_pin.preview.mesh_cache import preview_visual_model, start_mesh_prefetch
    from ipromp_pin.robot import load_robot

    monkeypatch.setenv("IPROMP_PIN_CACHE_DIR", str(tmp_path / "cache"))
    robot = load_robot("baxter_left")
    process = start_mesh_prefetch(robot)
    assert process is not None  # nothing cached yet: decimated in another process
    visual = preview_visual_model(robot, process)
    assert process.exitcode == 0 and visual.ngeoms > 0
    assert list((tmp_path / "cache" / "meshes").glob("*.npz"))  # the other process wrote the cache
    assert start_mesh_prefetch(robot) is None  # cached: nothing to do
    again = preview_visual_model(robot)
    assert again.ngeoms == visual.ngeoms
