"""Generate swimmer_mjcf/swimmer.xml: the layered-swimming paper's 16-box humanoid.

    python -m flapsim.swim.build.swimmer [--out FILE]

writes the bundled ``swimmer_mjcf/swimmer.xml`` (or ``--out``). The bundled file is this
module's output, byte for byte (``tests/swim/test_build.py``): change the design here, then
regenerate it.

Sources for every number (the paper took its segments from Wooten & Hodgins 1996,
which are not published in a usable table, so flapsim uses published anthropometry):

* total mass 89.57 kg and density 1.044 g/mL: Yang, Laszlo & Singh 2004 (the paper);
* segment mass fractions and lengths: de Leva 1996, "Adjustments to Zatsiorsky-
  Seluyanov's segment inertia parameters", J Biomech 29:1223, Table 4 (male):
  head+neck 6.94 % (VERT-CERV 24.29 cm), upper trunk 15.96 % (CERV-XYPH 24.21 cm),
  middle trunk 16.33 % (XYPH-OMPH 21.55 cm), lower trunk 11.17 % (OMPH-MIDH 14.57 cm),
  upper arm 2.71 % (28.17 cm), forearm 1.62 % (26.89 cm), hand 0.61 %, thigh 14.16 %
  (42.22 cm), shank 4.33 % (43.40 cm), foot 1.37 % (25.81 cm); lengths scaled from de
  Leva's 174.1 cm reference stature to STATURE;
* hand length (wrist to fingertip) 0.108 x stature: Drillis & Contini 1966 (de Leva's
  hand length stops at the third metacarpal, too short for a paddle);
* cross sections: each box's volume is its mass / 1044 kg/m^3 (the paper's cadaveric
  density); the width:depth ratios below are flapsim's assumptions (approximate body
  breadths/depths), stated per segment;
* the upper trunk is enlarged by LUNG_L litres of air (the paper: "up to 3 L"), same
  mass: at 3 L the paper reports a buoyancy of 91 kg, which is 88.8 L of sea water
  (1025 kg/m^3); flapsim.swim.model can set any lung volume at load time;
* joint torque limits: approximate adult male maximal isometric torques (order of
  magnitude from the biomechanics literature, e.g. Anderson et al. 2007 J Biomech
  40:3105 for hip/knee/ankle; shoulder/elbow from Chaffin & Andersson, Occupational
  Biomechanics); they only clip the PD muscles.

Frame: the model is built standing (x anterior, y left, z up); flapsim.swim.model lays
it prone for the swimming strokes. 16 segments, 16 anatomical joints (free root, 7 ball
joints, elbows and ankles with 2 hinges, knees and wrists with 1), 39 DOF.
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path

from flapsim.core.assets import asset_dir
from flapsim.core.io import atomic_path

TOTAL_MASS = 89.57  # kg (paper)
DENSITY = 1044.0  # kg/m^3 (paper)
STATURE = 1.80  # m (flapsim's choice for an 89.57 kg adult male)
DE_LEVA_STATURE = 1.741  # m
LUNG_L = 3.0  # litres of extra upper-trunk volume in the shipped XML
K = STATURE / DE_LEVA_STATURE

# name: (mass fraction %, length [m] along the segment axis, width:depth ratio)
SEGMENTS = {
    "pelvis": (11.17, 0.1457 * K, 1.45),  # lower trunk OMPH-MIDH
    "abdomen": (16.33, 0.2155 * K, 1.40),  # middle trunk XYPH-OMPH
    "thorax": (15.96, 0.2421 * K, 1.45),  # upper trunk CERV-XYPH
    "head": (6.94, 0.2429 * K, 0.80),  # head + neck VERT-CERV (deeper than wide)
    "upper_arm": (2.71, 0.2817 * K, 1.00),
    "forearm": (1.62, 0.2689 * K, 1.25),
    "hand": (0.61, 0.108 * STATURE, 3.50),  # flat paddle: width 3.5 x thickness
    "thigh": (14.16, 0.4222 * K, 1.00),
    "shank": (4.33, 0.4340 * K, 1.00),
    "foot": (1.37, 0.2581 * K, 1.60),  # heel to toe; width 1.6 x height
}

# Approximate maximal joint torques [N m] (see module docstring).
TORQUE = {
    "lumbar": 250.0, "thoracic": 200.0, "neck": 50.0, "shoulder": 120.0, "elbow": 80.0,
    "pronation": 15.0, "wrist": 25.0, "hip": 250.0, "knee": 200.0, "ankle": 120.0,
    "inversion": 40.0,
}


def seg(name: str, lung_l: float = 0.0) -> tuple[float, float, float, float]:
    """(mass [kg], length, width, depth [m]) of a segment."""
    pct, length, ratio = SEGMENTS[name]
    mass = TOTAL_MASS * pct / 100.0
    vol = mass / DENSITY + lung_l * 1e-3
    area = vol / length
    depth = math.sqrt(area / ratio)
    return mass, length, ratio * depth, depth


def f(*xs: float) -> str:
    return " ".join(f"{x:.5g}" for x in xs)


def box(name: str, mass: float, half: tuple[float, float, float], pos, rgba: str) -> str:
    return (f'<geom name="{name}" type="box" size="{f(*half)}" pos="{f(*pos)}" '
            f'mass="{mass:.7g}" rgba="{rgba}"/>')


SKIN = "0.85 0.66 0.55 1"
SUIT = "0.15 0.25 0.55 1"


def build(lung_l: float = LUNG_L) -> str:
    pm, pl, pw, pd = seg("pelvis")
    am, al, aw, ad = seg("abdomen")
    tm, tl, tw, td = seg("thorax", lung_l)
    hm, hl, hw, hd = seg("head")
    um, ul, uw, ud = seg("upper_arm")
    fm, fl, fw, fd = seg("forearm")
    nm, nl, nw, nt = seg("hand")
    gm, gl, gw, gd = seg("thigh")
    sm, sl, sw, sd = seg("shank")
    km, kl, kw, kh = seg("foot")
    heel = 0.06  # ankle joint is 6 cm in front of the heel (approx.)
    # the shoulder joint sits below the top of the upper trunk, beside it
    sh_z, sh_y = tl - 0.05, 0.5 * tw + 0.5 * uw
    hip_y = 0.5 * gw
    lines = []
    add = lines.append

    def limb_arm(side: str, s: float) -> None:
        # s = +1 left, -1 right; zero pose: arm hanging, palm facing the thigh
        add(f'<body name="upper_arm_{side}" pos="0 {f(s * sh_y)} {f(sh_z)}">')
        add(f'  <joint name="shoulder_{side}" type="ball" range="0 180" '
            f'class="shoulder"/>')
        add("  " + box(f"upper_arm_{side}", um, (ud / 2, uw / 2, ul / 2), (0, 0, -ul / 2), SKIN))
        add(f'  <body name="forearm_{side}" pos="0 0 {f(-ul)}">')
        add(f'    <joint name="elbow_flex_{side}" axis="0 -1 0" range="0 150" class="elbow"/>')
        add(f'    <joint name="elbow_pron_{side}" axis="0 0 {f(-s)}" range="-90 90" '
            f'class="pronation"/>')
        add("    " + box(f"forearm_{side}", fm, (fw / 2, fd / 2, fl / 2), (0, 0, -fl / 2), SKIN))
        add(f'    <body name="hand_{side}" pos="0 0 {f(-fl)}">')
        add(f'      <joint name="wrist_{side}" axis="{f(-s)} 0 0" range="-70 80" class="wrist"/>')
        add("      " + box(f"hand_{side}", nm, (nw / 2, nt / 2, nl / 2), (0, 0, -nl / 2), SKIN))
        add("    </body>")
        add("  </body>")
        add("</body>")

    def limb_leg(side: str, s: float) -> None:
        add(f'<body name="thigh_{side}" pos="0 {f(s * hip_y)} {f(-pl / 2)}">')
        add(f'  <joint name="hip_{side}" type="ball" range="0 130" class="hip"/>')
        add("  " + box(f"thigh_{side}", gm, (gd / 2, gw / 2, gl / 2), (0, 0, -gl / 2), SUIT))
        add(f'  <body name="shank_{side}" pos="0 0 {f(-gl)}">')
        add('    <joint name="knee_' + side + '" axis="0 1 0" range="0 150" class="knee"/>')
        add("    " + box(f"shank_{side}", sm, (sd / 2, sw / 2, sl / 2), (0, 0, -sl / 2), SKIN))
        add(f'    <body name="foot_{side}" pos="0 0 {f(-sl)}">')
        add(f'      <joint name="ankle_flex_{side}" axis="0 1 0" range="-30 70" class="ankle"/>')
        add(f'      <joint name="ankle_inv_{side}" axis="{f(-s)} 0 0" range="-35 35" '
            f'class="inversion"/>')
        add("      " + box(f"foot_{side}", km, (kl / 2, kw / 2, kh / 2),
                           (kl / 2 - heel, 0, -kh / 2), SKIN))
        add("    </body>")
        add("  </body>")
        add("</body>")

    add('<body name="pelvis" pos="0 0 0" childclass="swimmer">')
    add('  <freejoint name="root"/>')
    add("  " + box("pelvis", pm, (pd / 2, pw / 2, pl / 2), (0, 0, 0), SUIT))
    add('  <camera name="side" pos="0.2 -3.2 0.4" xyaxes="1 0 0 0 0 1" mode="trackcom"/>')
    add('  <camera name="top" pos="-0.4 0 3.5" xyaxes="0 -1 0 1 0 0" mode="trackcom"/>')
    add(f'  <body name="abdomen" pos="0 0 {f(pl / 2)}">')
    add('    <joint name="lumbar" type="ball" range="0 50" class="lumbar"/>')
    add("    " + box("abdomen", am, (ad / 2, aw / 2, al / 2), (0, 0, al / 2), SKIN))
    add(f'    <body name="thorax" pos="0 0 {f(al)}">')
    add('      <joint name="thoracic" type="ball" range="0 45" class="thoracic"/>')
    add("      " + box("thorax", tm, (td / 2, tw / 2, tl / 2), (0, 0, tl / 2), SKIN))
    add(f'      <body name="head" pos="0 0 {f(tl)}">')
    add('        <joint name="neck" type="ball" range="0 80" class="neck"/>')
    add("        " + box("head", hm, (hd / 2, hw / 2, hl / 2), (0, 0, hl / 2), SKIN))
    add("      </body>")
    body_start = len(lines)
    limb_arm("l", 1.0)
    limb_arm("r", -1.0)
    for k in range(body_start, len(lines)):
        lines[k] = "      " + lines[k]
    add("    </body>")
    add("  </body>")
    start = len(lines)
    limb_leg("l", 1.0)
    limb_leg("r", -1.0)
    for k in range(start, len(lines)):
        lines[k] = "  " + lines[k]
    add("</body>")
    body = "\n    ".join(lines)

    motors = []
    order = [("lumbar", 3, "lumbar"), ("thoracic", 3, "thoracic"), ("neck", 3, "neck")]
    for side in ("l", "r"):
        order += [(f"shoulder_{side}", 3, "shoulder"), (f"elbow_flex_{side}", 1, "elbow"),
                  (f"elbow_pron_{side}", 1, "pronation"), (f"wrist_{side}", 1, "wrist")]
    for side in ("l", "r"):
        order += [(f"hip_{side}", 3, "hip"), (f"knee_{side}", 1, "knee"),
                  (f"ankle_flex_{side}", 1, "ankle"), (f"ankle_inv_{side}", 1, "inversion")]
    for joint, ndof, kind in order:
        lim = TORQUE[kind]
        for k in range(ndof):
            gear = "" if ndof == 1 else f' gear="{f(*[1.0 if i == k else 0.0 for i in range(6)])}"'
            suffix = "" if ndof == 1 else "_" + "xyz"[k]
            motors.append(f'<motor name="{joint}{suffix}" joint="{joint}"{gear} '
                          f'ctrlrange="{f(-lim, lim)}"/>')
    motor_text = "\n    ".join(motors)

    total_vol = sum(seg(n)[0] for n in SEGMENTS) / DENSITY  # noqa: F841 (documentation)
    return f"""<!-- GENERATED by flapsim/swim/build/swimmer.py: edit the module, not this file.
  The layered-swimming paper's humanoid (Yang, Laszlo & Singh 2004): 16 box segments,
  16 anatomical joints, 39 DOF, {TOTAL_MASS} kg, density {DENSITY / 1000:g} g/mL before the
  lungs; upper trunk enlarged by {LUNG_L:g} L of air. Segment masses and lengths: de Leva 1996
  (J Biomech 29:1223, Table 4, male) scaled to {STATURE} m; hand length Drillis & Contini
  1966; box cross sections from volume = mass / density (see the module for every source).
  Built standing (x anterior, y left, z up). Zero pose: arms hanging with palms facing the
  thighs, legs straight, feet at right angles. PD muscles: one motor per DOF (ctrl = torque,
  clipped at approximate maximal joint torques); the PD's velocity gain is the joint
  damping (integrated implicitly), flapsim.swim.muscles supplies kp (qd - q) + kv qd'. -->
<mujoco model="swimmer">
  <compiler angle="degree" autolimits="true"/>
  <option timestep="0.004" integrator="implicitfast" gravity="0 0 -9.81"/>
  <size memory="4M"/>
  <default>
    <default class="swimmer">
      <geom contype="2" conaffinity="1" condim="3" friction="0.5 0.005 0.0001"/>
      <joint limited="true" armature="0.0"/>
      <default class="lumbar"><joint damping="40"/></default>
      <default class="thoracic"><joint damping="40"/></default>
      <default class="neck"><joint damping="6"/></default>
      <default class="shoulder"><joint damping="12"/></default>
      <default class="elbow"><joint damping="5"/></default>
      <default class="pronation"><joint damping="0.6"/></default>
      <default class="wrist"><joint damping="0.6"/></default>
      <default class="hip"><joint damping="30"/></default>
      <default class="knee"><joint damping="10"/></default>
      <default class="ankle"><joint damping="2"/></default>
      <default class="inversion"><joint damping="1"/></default>
    </default>
    <motor ctrllimited="true"/>
  </default>
  <visual><global offwidth="1280" offheight="720"/><quality shadowsize="2048"/></visual>
  <worldbody>
    <light name="sun" pos="0 0 6" dir="0 0 -1" directional="true"/>
    {body}
  </worldbody>
  <actuator>
    {motor_text}
  </actuator>
</mujoco>
"""


def write(out: str | Path) -> Path:
    """Write the swimmer's XML to the file ``out``; returns its path."""
    path = Path(out)
    with atomic_path(path) as tmp:
        tmp.write_text(build())
    return path


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default=None,
                    help="output file (default: the bundled swimmer_mjcf/swimmer.xml the package loads)")
    args = ap.parse_args(argv)
    out = write(args.out or asset_dir("swimmer_mjcf") / "swimmer.xml")
    print(f"wrote {out}")
    total = sum(seg(n)[0] * (2 if n in ("upper_arm", "forearm", "hand", "thigh", "shank", "foot")
                             else 1) for n in SEGMENTS)
    print(f"total mass {total:.3f} kg, volume {total / DENSITY * 1e3:.2f} L + {LUNG_L} L lungs")


if __name__ == "__main__":
    main()
