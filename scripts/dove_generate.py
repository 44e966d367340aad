"""Generate bird_mjcf/dove.xml from flapsim/bird/body/data/dove.toml (the one parameter file).

    PYTHONPATH=. python scripts/dove_generate.py [--params PATH] [--out PATH]

Prints the model's mass, span, wing area and DOF counts after compiling it.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from flapsim.bird.body.model import PARAM_FILE, Dove, DoveParams, all_feathers, build_xml
from flapsim.core.io import atomic_path

ROOT = Path(__file__).resolve().parents[1]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--params", default=str(PARAM_FILE))
    ap.add_argument("--out", default=str(ROOT / "bird_mjcf" / "dove.xml"))
    args = ap.parse_args()
    params = DoveParams.load(args.params)
    xml = build_xml(params)
    with atomic_path(args.out) as tmp:
        tmp.write_text(xml)
    dove = Dove.load(args.out, params)
    m = dove.model
    areas = {}
    for fe in all_feathers(params):
        areas[fe.kind] = areas.get(fe.kind, 0.0) + fe.area
    wing = sum(v for k, v in areas.items() if k != "rectrix")
    print(f"wrote {args.out}")
    print(f"mass {dove.mass:.4f} kg, bodies {m.nbody}, nq {m.nq}, nv {m.nv}, actuators {m.nu}, "
          f"tendons {m.ntendon}")
    print("feather areas (m^2): " + ", ".join(f"{k} {v:.4f}" for k, v in areas.items())
          + f"; wings {wing:.4f} -> wing loading {dove.mass / wing:.2f} kg/m^2")
    _, tris, _, _ = dove.feather_triangles()
    print(f"feather triangles {len(tris)}; span {2 * np.abs(_span(dove)):.3f} m")


def _span(dove: Dove) -> float:
    import mujoco

    d = mujoco.MjData(dove.model)
    mujoco.mj_forward(dove.model, d)
    y = []
    for g in dove.feather_geoms():
        mesh = dove.model.geom_dataid[g]
        v0, nv = dove.model.mesh_vertadr[mesh], dove.model.mesh_vertnum[mesh]
        v = dove.model.mesh_vert[v0:v0 + nv] @ d.geom_xmat[g].reshape(3, 3).T + d.geom_xpos[g]
        y.append(np.max(v[:, 1]))
    return float(max(y))


if __name__ == "__main__":
    main()
