"""Worlds: primitives, built-in worlds (the IMAV 2025 tunnel geometry), YAML descriptions, mesh files."""

import numpy as np
import pytest

import cufund
from cufund.core.config import ConfigError
from cufund.worlds import primitives


def cast(world, origin, direction):
    rays = np.array([[*origin, *direction]], np.float32)
    out = world.raycast_scene.cast_rays(rays)
    return float(out["t_hit"][0]), int(out["geometry_ids"][0])


@pytest.mark.parametrize(
    "mesh",
    [
        primitives.box((1.0, 2.0, 3.0)),
        primitives.cylinder(0.5, 2.0, 24),
        primitives.sphere(1.0, 2),
        primitives.tunnel_frame(0.5, 1.0, 0.05, 0.05),
    ],
)
def test_primitives_are_closed_and_outward_wound(mesh):
    v, f = mesh
    # Closed: every edge is shared by exactly two triangles, once in each direction.
    edges = np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]])
    fwd = {tuple(e) for e in edges.tolist()}
    assert len(fwd) == len(edges)
    assert all((b, a) in fwd for a, b in fwd)
    # Outward: the signed volume (divergence theorem) is positive.
    vol = np.sum(np.einsum("ij,ij->i", v[f[:, 0]], np.cross(v[f[:, 1]], v[f[:, 2]]))) / 6.0
    assert vol > 0


def test_box_and_cylinder_volumes():
    v, f = primitives.box((1.0, 2.0, 3.0))
    vol = np.sum(np.einsum("ij,ij->i", v[f[:, 0]], np.cross(v[f[:, 1]], v[f[:, 2]]))) / 6.0
    assert vol == pytest.approx(6.0)
    v, f = primitives.cylinder(0.5, 2.0, 64)
    vol = np.sum(np.einsum("ij,ij->i", v[f[:, 0]], np.cross(v[f[:, 1]], v[f[:, 2]]))) / 6.0
    n = 64
    assert vol == pytest.approx(0.5 * n * 0.25 * np.sin(2 * np.pi / n) * 2.0)  # inscribed polygon prism


def test_imav2025_tunnel_has_five_frames_over_two_metres_with_half_by_one_metre_openings():
    w = cufund.worlds.load("imav2025_tunnel")
    frames = [o for o in w.objects if o.label == "tunnel_frame"]
    assert len(frames) == 5
    centres_x = sorted(float(np.mean(o.vertices[:, 0])) for o in frames)
    np.testing.assert_allclose(centres_x, [0.0, 0.5, 1.0, 1.5, 2.0], atol=1e-9)
    # A ray down the tunnel's axis passes all five openings and hits the far wall (x = 7 m).
    t, gid = cast(w, (-1.0, 0.0, 0.55), (1.0, 0.0, 0.0))
    assert t == pytest.approx(8.0, abs=1e-5) and w.objects[gid].label == "wall"
    # Opening 0.5 m wide: y = ±0.24 passes, y = ±0.26 hits the first frame's post at x = -0.025 m.
    for y, hit_frame in ((0.24, False), (-0.24, False), (0.26, True), (-0.26, True)):
        t, gid = cast(w, (-1.0, y, 0.55), (1.0, 0.0, 0.0))
        assert (w.objects[gid].label == "tunnel_frame") == hit_frame
        if hit_frame:
            assert t == pytest.approx(0.975, abs=1e-5)
    # Opening 1 m tall: from z = 0.05 to 1.05 m.
    assert w.objects[cast(w, (-1.0, 0.0, 1.04), (1.0, 0.0, 0.0))[1]].label == "wall"
    assert w.objects[cast(w, (-1.0, 0.0, 1.06), (1.0, 0.0, 0.0))[1]].label == "tunnel_frame"
    # Floor, ceiling and walls enclose the arena.
    for d in ((0, 0, 1), (0, 0, -1), (0, 1, 0), (0, -1, 0), (-1, 0, 0)):
        assert np.isfinite(cast(w, (-1.0, 0.0, 0.55), d)[0])


def test_forest_is_seeded_and_keeps_a_clearing():
    a, b, c = (cufund.worlds.load("forest", seed=s) for s in (1, 1, 2))
    np.testing.assert_array_equal(a.objects[5].vertices, b.objects[5].vertices)
    assert not np.array_equal(a.objects[5].vertices, c.objects[5].vertices)
    trees = [o for o in a.objects if o.label == "tree"]
    assert len(trees) == 120
    assert min(np.hypot(*np.mean(o.vertices[:, :2], axis=0)) for o in trees) >= 2.0 - 0.3


def test_corridor_and_empty():
    w = cufund.worlds.load("corridor", width=2.0)
    assert cast(w, (5.0, 0.0, 1.0), (0.0, 1.0, 0.0))[0] == pytest.approx(1.0, abs=1e-5)
    assert np.isinf(cast(w, (5.0, 0.0, 1.0), (1.0, 0.0, 0.0))[0])  # open end
    e = cufund.worlds.load("empty")
    assert cast(e, (0.0, 0.0, 2.0), (0.0, 0.0, -1.0))[0] == pytest.approx(2.0)


def test_unknown_world_names_the_choices():
    with pytest.raises(ValueError, match="unknown world 'moon'.*imav2025_tunnel"):
        cufund.worlds.load("moon")


@pytest.mark.parametrize("ext", ["obj", "stl", "ply"])
def test_mesh_files_load_in_every_format(tmp_path, ext):
    trimesh = pytest.importorskip("trimesh")
    trimesh.creation.box(extents=(1.0, 2.0, 3.0)).export(tmp_path / f"m.{ext}")
    w = cufund.World()
    obj = w.load_mesh(tmp_path / f"m.{ext}", position=(5.0, 0.0, 0.0), yaw=np.pi / 2, color=(0.1, 0.2, 0.3))
    assert obj.label == "m" and len(obj.triangles) == 12
    # Yawed 90°, the 2 m side lies along x: the near face is at x = 4.
    assert cast(w, (0.0, 0.0, 0.0), (1.0, 0.0, 0.0))[0] == pytest.approx(4.0, abs=1e-5)


def test_yaml_world_with_mesh_file(tmp_path):
    trimesh = pytest.importorskip("trimesh")
    trimesh.creation.box(extents=(1.0, 1.0, 1.0)).export(tmp_path / "crate.obj")
    (tmp_path / "w.yaml").write_text(
        "name: yard\n"
        "objects:\n"
        "  - {type: plane, size: [20, 20], position: [0, 0, 0]}\n"
        "  - {type: box, size: [1, 1, 2], position: [3, 0, 1], label: crate, color: [0.6, 0.4, 0.2]}\n"
        "  - {type: mesh, path: crate.obj, position: [-3, 0, 0.5], scale: 2.0, label: big_crate}\n"
        "  - {type: sphere, radius: 0.5, position: [0, 3, 1]}\n"
        "  - {type: cylinder, radius: 0.2, height: 3, position: [0, -3, 1.5]}\n"
        "  - {type: tunnel_frame, position: [6, 0, 1]}\n"
    )
    w = cufund.worlds.load(str(tmp_path / "w.yaml"))
    assert w.name == "yard" and len(w) == 6
    assert w.objects[1].color == (0.6, 0.4, 0.2)
    t, gid = cast(w, (0.0, 0.0, 0.5), (-1.0, 0.0, 0.0))
    assert w.objects[gid].label == "big_crate" and t == pytest.approx(2.0, abs=1e-5)  # 2 m cube at x = -3
    t, gid = cast(w, (0.0, 0.0, 1.0), (0.0, 1.0, 0.0))
    assert t == pytest.approx(2.5, abs=0.02)  # icosphere of radius 0.5 at y = 3


@pytest.mark.parametrize(
    "text, message",
    [
        (
            "objects:\n  - {type: box, size: [1, 1, 1], position: [0, 0, 0], colour: [1, 0, 0]}\n",
            "unknown key 'colour' in objects\\[0\\] \\(box\\)",
        ),
        ("objects:\n  - {type: cone}\n", "objects\\[0\\].type must be one of"),
        ("objects:\n  - {type: box, position: [0, 0, 0]}\n", "objects\\[0\\] \\(box\\).*size"),
        (
            "objects:\n  - {type: box, size: [1, -1, 1], position: [0, 0, 0]}\n",
            "size\\[1\\] must be a finite number > 0",
        ),
        ("walls: []\n", "unknown key 'walls'"),
        (
            "objects:\n  - {type: cylinder, radius: 1, height: 1, position: [0, 0, 0], segments: 1e8}\n",
            "segments must be an integer, got 100000000.0",
        ),
        (
            "objects:\n  - {type: cylinder, radius: 1, height: 1, position: [0, 0, 0], segments: 100000000}\n",
            r"segments must be in \[3, 4096\], got 100000000 \(mesh_max_segments = 4096",
        ),
        (
            "objects:\n  - {type: sphere, radius: 1, position: [0, 0, 0], subdivisions: 2.5}\n",
            "subdivisions must be an integer, got 2.5",
        ),
        ("objects:\n  - {type: mesh, path: 7, position: [0, 0, 0]}\n", r"objects\[0\].path must be a file name"),
    ],
)
def test_bad_yaml_worlds_raise_config_error(tmp_path, text, message):
    path = tmp_path / "bad.yaml"
    path.write_text(text)
    with pytest.raises(ConfigError, match=message):
        cufund.worlds.load(str(path))


def test_add_mesh_validates_input():
    w = cufund.World()
    with pytest.raises(ValueError, match=r"vertices must have shape \(V, 3\)"):
        w.add_mesh(np.zeros((3, 2)), [[0, 1, 2]])
    with pytest.raises(ValueError, match=r"triangles must have shape \(T, 3\) with T >= 1"):
        w.add_mesh(np.zeros((3, 3)), np.zeros((0, 3), int))
    with pytest.raises(ValueError, match=r"triangles must index vertices in \[0, 3\)"):
        w.add_mesh(np.zeros((3, 3)), [[0, 1, 3]])
    with pytest.raises(ValueError, match="color must be 3 numbers in"):
        w.add_box((1, 1, 1), (0, 0, 0), color=(2, 0, 0))
    with pytest.raises(ValueError, match="does not exist"):
        w.load_mesh("/nonexistent/mesh.obj")
    assert len(w) == 0


def test_scene_is_rebuilt_after_adding_objects():
    w = cufund.World()
    w.add_box((1, 1, 1), (5, 0, 0))
    assert cast(w, (0, 0, 0), (1, 0, 0))[0] == pytest.approx(4.5)
    w.add_box((1, 1, 1), (2, 0, 0))
    assert cast(w, (0, 0, 0), (1, 0, 0)) == (pytest.approx(1.5), 1)


def test_forest_with_an_impossible_clearing_fails_fast():
    with pytest.raises(ValueError, match=r"clearing must be < size / sqrt\(2\) = 0.707 m"):
        cufund.worlds.load("forest", n_trees=3, size=1.0, clearing=5.0)  # looped forever before
    # Room for only a sliver: the bounded number of draws ends it with a message.
    with pytest.raises(ValueError, match="could not place 50 trees outside a clearing of 0.7 m in a 1.0 m square"):
        cufund.worlds.load("forest", n_trees=50, size=1.0, clearing=0.7)
    for kwargs, message in [
        ({"n_trees": 2.5}, "n_trees must be an integer"),
        ({"size": float("nan")}, "size must be a finite number > 0"),
        ({"clearing": -1.0}, "clearing must be a finite number >= 0"),
    ]:
        with pytest.raises(ValueError, match=message):
            cufund.worlds.load("forest", **kwargs)


def test_obj_face_index_zero_and_out_of_range_are_rejected(tmp_path):
    verts = "v 0 0 0\nv 1 0 0\nv 0 1 0\n"
    for face, message in [
        ("f 0 1 2", "bad.obj:4: face index 0 must be in \\[1, 3\\]"),
        ("f 1 2 4", "bad.obj:4: face index 4 must be in \\[1, 3\\]"),
        ("f 1 2 x", "bad.obj:4: face index 'x' is not an integer"),
    ]:
        (tmp_path / "bad.obj").write_text(verts + face + "\n")
        with pytest.raises(ValueError, match=message):
            cufund.World().load_mesh(tmp_path / "bad.obj")
    (tmp_path / "ok.obj").write_text(verts + "f 1 2 -1\n")  # -1: the last vertex
    obj = cufund.World().load_mesh(tmp_path / "ok.obj")
    assert obj.vertices[obj.triangles[0]].tolist() == [[0, 0, 0], [1, 0, 0], [0, 1, 0]]


def test_unreadable_mesh_files_raise_value_error_naming_the_file(tmp_path):
    pytest.importorskip("trimesh")
    cases = {
        "junk.stl": b"solid x\nfacet normal 0 0 1\nouter loop\nvertex 0 0\n",
        "junk.ply": b"ply\nformat ascii 1.0\n",
        "empty.obj": b"# nothing\n",
        "junk.glb": b"glTF\x02\x00\x00\x00",
    }
    for name, data in cases.items():
        (tmp_path / name).write_bytes(data)
        with pytest.raises(ValueError, match=f"mesh file .*{name}"):
            cufund.World().load_mesh(tmp_path / name)
