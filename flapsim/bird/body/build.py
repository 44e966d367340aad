"""Generate the bundled dove model, bird_mjcf/dove.xml, from its one parameter file
(flapsim/bird/body/data/dove.toml).

    python -m flapsim.bird.body.build [--params PATH] [--out PATH]

Writes the model (default: the bundled ``bird_mjcf/dove.xml`` the package loads), then compiles
it and prints its mass, span, wing area and DOF counts. The bundled file is this generator's
output, byte for byte (``tests/bird/body/test_build.py``): edit ``dove.toml`` or
:func:`flapsim.bird.body.model.build_xml`, never the XML, then regenerate it. The synthetic
capture the flight reads has its own generator: ``python -m flapsim.bird.flight.synthetic_capture``.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import mujoco
import numpy as np

from flapsim.bird.body.model import Dove, build_xml
from flapsim.bird.body.params import PARAM_FILE, DoveParams, all_feathers
from flapsim.core.assets import asset_dir
from flapsim.core.io import atomic_path


def write(out: str | Path, params: DoveParams | None = None) -> Path:
    """Write the dove's MJCF built from ``params`` (default: ``dove.toml``) to ``out``."""
    path = Path(out)
    xml = build_xml(params if params is not None else DoveParams.load(PARAM_FILE))
    with atomic_path(path) as tmp:
        tmp.write_text(xml)
    return path


def summary(dove: Dove) -> list[str]:
    """Lines describing the compiled model: sizes, feather areas, wing loading, span."""
    m = dove.model
    areas: dict[str, float] = {}
    for fe in all_feathers(dove.params):
        areas[fe.kind] = areas.get(fe.kind, 0.0) + fe.area
    wing = sum(v for k, v in areas.items() if k != "rectrix")
    _, tris, _, _ = dove.feather_triangles()
    return [f"mass {dove.mass:.4f} kg, bodies {m.nbody}, nq {m.nq}, nv {m.nv}, actuators {m.nu}, "
            f"tendons {m.ntendon}",
            "feather areas (m^2): " + ", ".join(f"{k} {v:.4f}" for k, v in areas.items())
            + f"; wings {wing:.4f} -> wing loading {dove.mass / wing:.2f} kg/m^2",
            f"feather triangles {len(tris)}; span {2 * abs(_half_span(dove)):.3f} m"]


def _half_span(dove: Dove) -> float:
    """The largest y of any feather vertex at the rest pose (the left wing tip), m."""
    d = mujoco.MjData(dove.model)
    mujoco.mj_forward(dove.model, d)
    y = []
    for g in dove.feather_geoms():
        mesh = dove.model.geom_dataid[g]
        v0, nv = dove.model.mesh_vertadr[mesh], dove.model.mesh_vertnum[mesh]
        v = dove.model.mesh_vert[v0:v0 + nv] @ d.geom_xmat[g].reshape(3, 3).T + d.geom_xpos[g]
        y.append(np.max(v[:, 1]))
    return float(max(y))


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--params", default=str(PARAM_FILE), help="parameter file (default: dove.toml)")
    ap.add_argument("--out", default=None,
                    help="output file (default: the bundled bird_mjcf/dove.xml the package loads)")
    args = ap.parse_args(argv)
    params = DoveParams.load(args.params)
    out = write(args.out or asset_dir("bird_mjcf") / "dove.xml", params)
    print(f"wrote {out}")
    print("\n".join(summary(Dove.load(out, params))))


if __name__ == "__main__":
    main()
