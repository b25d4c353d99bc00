"""Fuzz: YAML loading (config.load_yaml, vehicle and world files), world builders and mesh files."""

from __future__ import annotations

from fuzz_support import arrays, expect_good, floats_any, fuzz_settings, scalars
from hypothesis import given
from hypothesis import strategies as st

LAUGHS = "\n".join(
    ['a: &a ["lol","lol","lol","lol","lol","lol","lol","lol","lol"]']
    + [f"{c}: &{c} [{', '.join(['*' + p] * 9)}]" for p, c in zip("abcdefgh", "bcdefghi", strict=True)]
)
HOSTILE = [
    LAUGHS,
    "a: &x [1, *x]\n",
    "a: &x {b: *x}\n",
    "[" * 3000 + "]" * 3000,
    "{a: " * 500 + "1" + "}" * 500,
    "!!python/object/apply:os.system ['true']\n",
    "a: !!binary AAAA\n",
    "--- 1\n--- 2\n",
    "\x00\x01",
    "mass: .nan\ninertia: [1, 1, 1]\n",
    "mass: 1e400\n",
    "? [1, 2]\n: 3\n",
    "a: *undefined\n",
]
YAML_ATOMS = st.one_of(
    st.sampled_from(
        [
            "1",
            "-1",
            "0",
            ".nan",
            ".inf",
            "-.inf",
            "1e400",
            "1e-400",
            "true",
            "null",
            "'x'",
            "[]",
            "{}",
            "[1, 2, 3]",
            "[1, 2]",
            "[[1, 0, 0], [0, 1, 0], [0, 0, 1]]",
            "0x10",
            "1_000",
            "2**3",
            "~",
            "&a 1",
            "*a",
        ]
    ),
    st.text(alphabet=st.characters(blacklist_categories=("Cs",)), max_size=12),
)
VEHICLE_KEYS = [
    "mass",
    "inertia",
    "arm_length",
    "k_f",
    "c_m",
    "tau_m",
    "rotor_speed_max",
    "layout",
    "body_drag",
    "gravity",
    "ground_plane",
    "max_integration_step",
    "name",
    "unknown_key",
]
BASE_VEHICLE = {
    "mass": "1.0",
    "inertia": "[0.01, 0.01, 0.02]",
    "arm_length": "0.2",
    "k_f": "1.0e-5",
    "c_m": "0.02",
    "tau_m": "0.02",
    "rotor_speed_max": "1000.0",
}


def _write(tmp_path_factory, text: str | bytes) -> str:
    path = tmp_path_factory.mktemp("yaml") / "case.yaml"
    path.write_bytes(text if isinstance(text, bytes) else text.encode("utf-8", "surrogatepass"))
    return str(path)


@fuzz_settings
@given(text=st.one_of(st.sampled_from(HOSTILE), st.text(max_size=200), st.binary(max_size=64)))
def test_load_yaml(server, tmp_path_factory, text):
    outcome, detail = server.run(
        "yaml",
        "from cufund.core.config import load_yaml",
        "load_yaml(path)",
        {"path": _write(tmp_path_factory, text)},
        timeout=15,
    )
    expect_good(outcome, detail)


@fuzz_settings
@given(key=st.sampled_from(VEHICLE_KEYS), value=YAML_ATOMS)
def test_vehicle_yaml(server, tmp_path_factory, key, value):
    data = dict(BASE_VEHICLE, **{key: value})
    text = "".join(f"{k}: {v}\n" for k, v in data.items())
    code = """
p = cufund.QuadrotorParams.from_yaml(path)
q = cufund.Quadrotor(p)
q.hover(np.array([0.0, 0.0, 1.0]))
for _ in range(10):
    q.step(1e-3, np.full(4, p.hover_rotor_speed))
result = q.state.as_vector()
"""
    outcome, detail = server.run(
        "yaml", "", code, {"path": _write(tmp_path_factory, text)}, check="np.isfinite(result).all()"
    )
    expect_good(outcome, detail)


@fuzz_settings
@given(
    kind=st.sampled_from(["box", "plane", "cylinder", "sphere", "tunnel_frame", "mesh", "cone"]),
    key=st.sampled_from(
        [
            "size",
            "position",
            "radius",
            "height",
            "segments",
            "subdivisions",
            "yaw",
            "color",
            "path",
            "scale",
            "label",
            "width",
        ]
    ),
    value=YAML_ATOMS,
)
def test_world_yaml(server, tmp_path_factory, kind, key, value):
    base = {
        "box": "size: [1, 1, 1], position: [0, 0, 0]",
        "plane": "size: [2, 2], position: [0, 0, 0]",
        "cylinder": "radius: 0.2, height: 1, position: [0, 0, 0]",
        "sphere": "radius: 0.5, position: [0, 0, 0]",
        "tunnel_frame": "position: [0, 0, 0]",
        "mesh": "path: missing.obj",
        "cone": "",
    }[kind]
    text = f"name: fuzz\nobjects:\n  - {{type: {kind}, {base}{', ' if base else ''}{key}: {value}}}\n"
    outcome, detail = server.run(
        "worlds",
        "",
        "w = cufund.worlds.load(path)\nresult = w.raycast_scene.num_triangles",
        {"path": _write(tmp_path_factory, text)},
        timeout=15,
    )
    expect_good(outcome, detail)


@fuzz_settings
@given(
    n_trees=st.one_of(st.integers(-2, 300), scalars()),
    size=st.one_of(floats_any(), st.floats(0, 100)),
    clearing=st.one_of(floats_any(), st.floats(0, 100)),
    seed=st.one_of(st.integers(0, 2**64), scalars()),
)
def test_forest(server, n_trees, size, clearing, seed):
    outcome, detail = server.run(
        "worlds",
        "",
        "result = len(cufund.worlds.load('forest', seed=seed, n_trees=n_trees, size=size, clearing=clearing))",
        {"n_trees": n_trees, "size": size, "clearing": clearing, "seed": seed},
        timeout=15,
    )
    expect_good(outcome, detail)


@fuzz_settings
@given(
    ext=st.sampled_from(["obj", "stl", "ply", "off", "glb", "xyz"]),
    body=st.one_of(
        st.text(max_size=120),
        st.binary(max_size=80),
        st.lists(
            st.sampled_from(
                [
                    "v 0 0 0",
                    "v 1 0 0",
                    "v 0 1 0",
                    "v nan 0 0",
                    "v 1e400 0 0",
                    "f 1 2 3",
                    "f 0 1 2",
                    "f 1 2 9",
                    "f -1 -2 -3",
                    "f 1/1 2/2 3/3",
                    "f 1 2",
                    "vn 0 0 1",
                    "o x",
                    "usemtl m",
                    "mtllib missing.mtl",
                    "solid s",
                    "facet normal 0 0 1",
                    "outer loop",
                    "vertex 0 0 0",
                    "endloop",
                    "endfacet",
                    "ply",
                    "format ascii 1.0",
                    "element vertex 3",
                    "end_header",
                ]
            ),
            max_size=12,
        ).map("\n".join),
    ),
    scale=st.one_of(st.just(1.0), scalars()),
)
def test_mesh_files(server, tmp_path_factory, ext, body, scale):
    path = tmp_path_factory.mktemp("mesh") / f"case.{ext}"
    path.write_bytes(body if isinstance(body, bytes) else body.encode("utf-8", "surrogatepass"))
    outcome, detail = server.run(
        "worlds",
        "",
        "w = cufund.World()\nw.load_mesh(path, scale=scale)\nresult = w.raycast_scene.num_triangles",
        {"path": str(path), "scale": scale},
        timeout=15,
    )
    expect_good(outcome, detail)


@fuzz_settings
@given(
    shape=st.sampled_from(["box", "cylinder", "sphere", "plane", "tunnel_frame"]),
    a=st.one_of(scalars(), arrays([(3,), (2,)])),
    b=st.one_of(st.just(1.0), scalars()),
)
def test_primitives(server, shape, a, b):
    call = {
        "box": "primitives.box(a)",
        "cylinder": "primitives.cylinder(1.0, b, a)",
        "sphere": "primitives.sphere(b, a)",
        "plane": "primitives.plane(a)",
        "tunnel_frame": "primitives.tunnel_frame(a, b, 0.05, 0.05)",
    }[shape]
    outcome, detail = server.run(
        "worlds",
        "from cufund.worlds import primitives",
        "result = " + call + "[0]",
        {"a": a, "b": b},
        check="np.isfinite(result).all()",
    )
    expect_good(outcome, detail)
