"""How the dove looks in videos and the viewer: a Eurasian collared dove (*Streptopelia
decaocto*): pale grey-buff body, pinkish-buff head, the black half-collar on the nape, dark
red eyes, darker grey-brown primaries, a grey-brown tail whose outer feathers end in white;
under a sky gradient, over grass with a 2 m grid for scale, the sun casting shadows.

Only the *drawing* model is dressed (:meth:`flapsim.bird.body.model.Dove.drawing` and the
bent-feather :class:`flapsim.bird.body.drawing.FeatherDrawing`), never the model that is
simulated. Even there every added geom is display-only: no contact (``contype`` and
``conaffinity`` 0), no mass (``mass`` 0; the dove's inertias are given explicitly,
``inertiafromgeom="false"``), in geom group 1, and no mesh (the force engine's polygons are
the feather meshes): the drawing model's masses and inertias equal the dove's (tested).

Colours: field-guide descriptions of the species (Svensson et al., *Collins Bird Guide*),
as RGB 0-1 picked by eye against photographs."""

from __future__ import annotations

import xml.etree.ElementTree as ET

import mujoco
import numpy as np

from flapsim.render.world import grass_xml, sky_xml

BODY_RGBA = (0.80, 0.74, 0.66, 1.0)
"""Pale grey-buff."""
HEAD_RGBA = (0.82, 0.74, 0.72, 1.0)
"""Pinkish-buff."""
COLLAR_RGBA = (0.06, 0.06, 0.07, 1.0)
EYE_RGBA = (0.45, 0.04, 0.05, 1.0)
"""Dark red iris."""
FEATHER_RGBA = {  # by feather group (the geom name's letter after the side): top, underside
    "t": ((0.78, 0.71, 0.62, 1.0), (0.82, 0.80, 0.76, 1.0)),   # tertials: buff
    "s": ((0.66, 0.62, 0.58, 1.0), (0.80, 0.79, 0.77, 1.0)),   # secondaries: grey
    "p": ((0.38, 0.33, 0.30, 1.0), (0.62, 0.60, 0.58, 1.0)),   # primaries: dark grey-brown
    "r": ((0.58, 0.53, 0.48, 1.0), (0.40, 0.38, 0.37, 1.0)),   # rectrices: grey-brown
}
TAIL_TIP_RGBA = (0.97, 0.97, 0.95, 1.0)
"""The white tips of the outer tail feathers."""
OUTER_RECTRICES = (4, 5, 6)
"""Which rectrices (1 = central) have white tips."""
TIP_SHARE = 0.38
"""How much of an outer rectrix's length is white, from its tip."""
DISPLAY = {"contype": "0", "conaffinity": "0", "mass": "0", "group": "1"}
"""The attributes of every added geom: seen, never felt."""
GRID_M = 2.0
"""Side of the ground's squares, m."""


def dress(xml: str) -> str:
    """The dove's MJCF ``xml`` (a drawing model) in the collared dove's colours, with its
    display-only geoms and the sky, ground and light of the videos."""
    root = ET.fromstring(xml)
    tips = _rectrix_tips(xml)
    _scene(root)
    for body in root.iter("body"):
        for g in list(body.findall("geom")):
            name = g.get("name", "")
            _colour(g, name)
            if name == "neck":
                _collar(body, g)
            if name in tips:
                _tail_tip(body, g, *tips[name])
    return ET.tostring(root, encoding="unicode")


def _scene(root: ET.Element) -> None:
    asset = root.find("asset")
    for t in asset.findall("texture"):
        if t.get("name") == "sky":
            t.attrib.update(sky_xml())
        elif t.get("name") == "grid":
            t.attrib.update(grass_xml())
    for mat in asset.findall("material"):
        if mat.get("name") == "grid":
            # texuniform: the texture repeats per metre of the plane, each holding 2 x 2 squares
            mat.attrib.update(texuniform="true", texrepeat=f"{0.5 / GRID_M:g} {0.5 / GRID_M:g}",
                              reflectance="0")
        elif mat.get("name") == "plumage":
            mat.attrib.update(rgba=_v(BODY_RGBA), specular="0.15", shininess="0.2")
    vis = root.find("visual")
    if vis is not None:
        quality = vis.find("quality")
        if quality is None:
            quality = ET.SubElement(vis, "quality")
        quality.set("shadowsize", "4096")
        headlight = vis.find("headlight")
        if headlight is None:
            headlight = ET.SubElement(vis, "headlight")
        # a dim headlight: the sun's shading and shadows carry the shape
        headlight.attrib.update(ambient="0.25 0.25 0.25", diffuse="0.35 0.35 0.35",
                                specular="0.05 0.05 0.05")
    for light in root.iter("light"):
        if light.get("name") == "sun":
            light.attrib.update(castshadow="true", diffuse="0.75 0.73 0.68",
                                specular="0.2 0.2 0.2", dir="-0.3 0.25 -1")


def _colour(g: ET.Element, name: str) -> None:
    if name == "head":
        g.set("rgba", _v(HEAD_RGBA))
    elif name in ("l_eye", "r_eye"):
        g.set("rgba", _v(EYE_RGBA))
    elif len(name) > 2 and name[1] == "_" and name[2] in FEATHER_RGBA and name[3:4].isdigit():
        top, under = FEATHER_RGBA[name[2]]
        g.set("rgba", _v(under if name.endswith("_under") else top))


def _collar(body: ET.Element, neck: ET.Element) -> None:
    """The black half-collar: a thin slab across the neck, a little wider than it and raised,
    so that only its upper half shows, on the nape."""
    pos = np.array([float(v) for v in neck.get("pos").split()])
    a = np.array([float(v) for v in neck.get("size").split()])
    ET.SubElement(body, "geom", name="collar", type="ellipsoid",
                  size=_v([0.14 * a[0], 1.07 * a[1], 1.0 * a[2]]),
                  pos=_v(pos + [-0.1 * a[0], 0.0, 0.22 * a[2]]), euler=neck.get("euler", "0 0 0"),
                  rgba=_v(COLLAR_RGBA), **DISPLAY)


def _tail_tip(body: ET.Element, g: ET.Element, centre: np.ndarray, half: np.ndarray,
              xyaxes: np.ndarray) -> None:
    """A white box over the last :data:`TIP_SHARE` of a rectrix, in its body's frame, as thin
    as the feather drawn (both faces covered)."""
    ET.SubElement(body, "geom", name=g.get("name") + "_tip", type="box", size=_v(half),
                  pos=_v(centre), xyaxes=_v(xyaxes), rgba=_v(TAIL_TIP_RGBA), **DISPLAY)


def _rectrix_tips(xml: str) -> dict[str, tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """For each outer rectrix (top face): the centre, half-sizes and axes (body frame, m) of
    the box over its last :data:`TIP_SHARE`, from its mesh's vertices placed by the geom's
    pose: along the feather's length (its vertices' principal axis, toward the vertex
    farthest from the bone), across its vane, and through it."""
    m = mujoco.MjModel.from_xml_string(xml)
    out = {}
    for side in ("l", "r"):
        for k in OUTER_RECTRICES:
            name = f"{side}_r{k}"
            g = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, name)
            if g < 0 or m.geom_type[g] != mujoco.mjtGeom.mjGEOM_MESH:
                continue
            mesh = m.geom_dataid[g]
            v = m.mesh_vert[m.mesh_vertadr[mesh]:m.mesh_vertadr[mesh] + m.mesh_vertnum[mesh]]
            rot = np.zeros(9)
            mujoco.mju_quat2Mat(rot, m.geom_quat[g])
            v = v.astype(float) @ rot.reshape(3, 3).T + m.geom_pos[g]
            c = v.mean(0)
            axes = np.linalg.svd(v - c)[2]  # rows: length, width, thickness
            if (v[np.argmax(np.linalg.norm(v, axis=1))] - c) @ axes[0] < 0:
                axes[0] = -axes[0]
            axes[2] = np.cross(axes[0], axes[1])
            local = (v - c) @ axes.T
            lo, hi = local.min(0), local.max(0)
            start = hi[0] - TIP_SHARE * (hi[0] - lo[0])
            sel = local[local[:, 0] >= start]
            w = sel[:, 1].max() - sel[:, 1].min() if len(sel) else hi[1] - lo[1]
            mid_w = (sel[:, 1].max() + sel[:, 1].min()) / 2 if len(sel) else 0.0
            half = np.array([(hi[0] - start) / 2, w / 2, max((hi[2] - lo[2]) / 2, 0.0006)])
            centre = c + axes[0] * (hi[0] + start) / 2 + axes[1] * mid_w
            out[name] = (centre, half, axes[:2].ravel())
    return out


def _v(a) -> str:
    return " ".join(f"{float(x):.5g}" for x in a)
