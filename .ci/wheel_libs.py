"""Checks that an installed cufund wheel needs no library beyond what it ships and what manylinux allows.

Run with the interpreter of the venv the wheel was installed into, outside the source tree, with LD_LIBRARY_PATH
empty: python wheel_libs.py <auditwheel's manylinux-policy.json>

1. ldd on the installed cufund/_core*.so: every library it resolves (directly or through a bundled library) is
   either in the wheel's cufund.libs or on the allow-list of the manylinux policy the wheel is tagged with; none is
   missing, and lz4, zstd and libdeflate appear nowhere (linked in statically).
2. A ray cast through Embree (single rays and 8-wide packets, on every core) hits a plane at its analytic distance,
   and afterwards every Embree, TBB, Bullet and compression library mapped into the process comes from cufund.libs.
"""
import importlib.metadata
import json
import re
import subprocess
import sys
from pathlib import Path

import numpy as np

import cufund._core

BUNDLED = ("libembree3", "libtbb", "libBulletCollision", "libLinearMath")
STATIC = ("liblz4", "libzstd", "libdeflate")
LOADER = ("linux-vdso.so.1", "ld-linux-x86-64.so.2")


def wheel_policies(dist: importlib.metadata.Distribution) -> list[str]:
    """manylinux policy names from the installed wheel's WHEEL file (Tag: cp311-cp311-manylinux_2_35_x86_64)."""
    tags = [line.split(":", 1)[1].strip() for line in dist.read_text("WHEEL").splitlines()
            if line.startswith("Tag:")]
    names = sorted({re.sub(r"_x86_64$", "", t.split("-")[2]) for t in tags})
    if not names or not all(n.startswith("manylinux_") for n in names):
        sys.exit(f"FAIL: the installed wheel is not tagged manylinux: {tags}")
    return names


def allowed_names(policy_json: Path, names: list[str]) -> set[str]:
    policies = {p["name"]: p for p in json.loads(policy_json.read_text())}
    missing = [n for n in names if n not in policies]
    if missing:
        sys.exit(f"FAIL: policy {missing} is not in {policy_json}")
    return set.intersection(*(set(policies[n]["lib_whitelist"]) for n in names))


def main() -> None:
    policy_json = Path(sys.argv[1])
    dist = importlib.metadata.distribution("cufund")
    core = Path(cufund._core.__file__).resolve()
    libs = core.parent.parent / "cufund.libs"
    bundled = sorted(p.name for p in libs.iterdir()) if libs.is_dir() else []
    names = wheel_policies(dist)
    allowed = allowed_names(policy_json, names)
    print(f"installed wheel: {core.name} tagged {', '.join(names)}; cufund.libs: {', '.join(bundled)}")
    for stem in BUNDLED:
        if not any(b.startswith(stem) for b in bundled):
            sys.exit(f"FAIL: {stem} is not bundled in {libs}")

    ldd = subprocess.run(["ldd", str(core)], capture_output=True, text=True, check=True).stdout
    bad = []
    for line in ldd.splitlines():
        line = line.strip()
        name, _, rest = line.partition(" => ")
        name = name.split(" (")[0]
        path = rest.split(" (")[0] if rest else name
        base = Path(name).name
        if "not found" in rest:
            bad.append(f"{name}: not found")
        elif base in LOADER:
            continue
        elif Path(path).resolve().parent == libs.resolve():
            continue
        elif base not in allowed:
            bad.append(f"{name} => {path} (neither in cufund.libs nor allowed by {names[0]})")
        if base.startswith(STATIC):
            bad.append(f"{name} => {path} (should be linked statically)")
    if bad:
        sys.exit("FAIL: the wheel's _core needs libraries from outside it:\n  " + "\n  ".join(bad) + "\n" + ldd)
    n_libs = sum(1 for line in ldd.splitlines() if line.strip())
    print(f"installed wheel: ldd resolves {n_libs} libraries, each in cufund.libs or allowed by {names[0]}")

    # A triangle pair covering the plane z = 2 over [-10, 10]^2; rays from the origin into the upper half-space
    # hit it at t = 2 / d_z (unit directions), from one origin (packets) and from scattered origins (single rays).
    scene = cufund._core.lidar.RaycastScene()
    scene.add_triangles(np.array([[-10, -10, 2], [10, -10, 2], [10, 10, 2], [-10, 10, 2]], float),
                        np.array([[0, 1, 2], [0, 2, 3]]))
    rng = np.random.default_rng(7)
    d = rng.normal(size=(20000, 3))
    d[:, 2] = np.abs(d[:, 2]) + 1.0
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    for coherent in (True, False):
        o = np.zeros_like(d) if coherent else np.c_[rng.uniform(-1, 1, (len(d), 2)), np.zeros(len(d))]
        hit = scene.cast_rays(np.c_[o, d].astype(np.float32), coherent=coherent)
        expected = 2.0 / d[:, 2]
        inside = np.all(np.abs(o[:, :2] + expected[:, None] * d[:, :2]) < 9.99, axis=1)
        err = np.abs(hit["t_hit"][inside] - expected[inside])
        if inside.sum() < 1000 or not np.all(err < 1e-4 * expected[inside]):
            sys.exit(f"FAIL: ray cast (coherent={coherent}): {inside.sum()} rays on the plane, max |t - 2/d_z| "
                     f"{err.max() if err.size else None}")
    print(f"installed wheel: {len(d)} rays x 2 (packets, single) hit the plane z = 2 at 2 / d_z (Embree from the "
          "wheel)")
    mapped = {line.split()[-1] for line in Path("/proc/self/maps").read_text().splitlines()
              if len(line.split()) >= 6 and line.split()[-1].startswith("/")}
    ours = [m for m in mapped if Path(m).name.startswith(BUNDLED + STATIC)]
    outside = [m for m in ours if Path(m).resolve().parent != libs.resolve()]
    if outside or not ours:
        sys.exit(f"FAIL: libraries mapped from outside cufund.libs after the ray cast: {outside or 'none mapped'}")
    print(f"installed wheel: mapped after the ray cast, all from cufund.libs: "
          f"{', '.join(sorted(Path(m).name for m in ours))}")


if __name__ == "__main__":
    main()
