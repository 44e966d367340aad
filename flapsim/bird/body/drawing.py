"""Drawing bent feathers: a display model of the modal dove whose feather meshes follow the
modal coordinates of a recorded flight frame (videos and the viewer). Nothing here exerts a
force; the dove's own model is untouched."""

from __future__ import annotations

import xml.etree.ElementTree as ET

import mujoco
import numpy as np

from flapsim.bird.body.feather_dynamics import ModalFeathers, _v, dove_feather_modes, warp
from flapsim.bird.body.feather_modes import FeatherModes
from flapsim.bird.body.model import build_xml
from flapsim.bird.body.params import UNDERSIDE
from flapsim.bird.body.plumage import dress
from flapsim.core.errors import InputError, ModelError
from flapsim.fluid.coefficients import CoefficientTable, get_table


class FeatherDrawing:
    """A display copy of a modal dove whose feathers are drawn bent: the videos' and the
    viewer's one way of drawing them.

    Each feather's two mesh geoms (top and underside) are replaced by a MuJoCo flex of the
    same vertices and triangles on the same bone, and :meth:`apply` writes each feather's
    deformed vertices (the warp the force engine uses, :meth:`ModalFeathers.body_vertices`)
    into ``flex_vert`` (the flex's vertices in its bone's frame). MuJoCo turns them into
    world points in ``mj_forward`` (``flexvert_xpos``) and every renderer draws flexes from
    those each frame. Why flexes: bent *meshes* must be re-uploaded to the GL context per
    frame, one ``mjr_uploadMesh`` per mesh; the passive viewer does that one mesh per render
    loop pass (~70 ms each under Xvfb: 8 s a frame for the dove's 112 feather meshes), a
    flex costs nothing to upload. The flex collides with nothing (contype = conaffinity = 0).

    What is drawn is a *frame* of the flight (:meth:`~flapsim.bird.flight.dove_flight.DoveFlight.frame`):
    its ``qpos``, then (engine-integrated modes) the modal coordinates. ``frame[ix]`` is the
    display model's ``qpos``: for engine-integrated modes the dove with its twist hinges in
    the primaries' bodies (drawn twisted) plus one display-only slide joint per mode that
    holds its coordinate; for modes on joints the modal dove's own layout. The dove's own
    model is untouched.

    Use::
        draw = FeatherDrawing(dove)
        d = mujoco.MjData(draw.model)
        d.qpos[:] = flight.frame()[draw.ix]; draw.apply(d); mujoco.mj_forward(draw.model, d)
    """

    def __init__(self, dove) -> None:
        if dove.modal is None:
            raise InputError("FeatherDrawing draws a modal dove (Dove.load(feathers='modal'))")
        modes = dove_feather_modes(dove.params, dove.modal)
        engine = dove.modal.integration == "engine"
        root = ET.fromstring(dress(build_xml(dove.params, twist="tree") if engine else
                                   build_xml(dove.params, modal=dove.modal)))
        # a bent feather's white tip would not bend with it: those go too
        gone = ({fm.name for fm in modes} | {fm.name + UNDERSIDE for fm in modes}
                | {fm.name + "_tip" for fm in modes})
        rgba = {}
        for g in range(dove.model.ngeom):
            rgba[mujoco.mj_id2name(dove.model, mujoco.mjtObj.mjOBJ_GEOM, g)] = dove.model.geom_rgba[g]
        for body in root.iter("body"):
            for g in list(body.findall("geom")):
                if g.get("rgba") and g.get("name"):  # the species' colours
                    rgba[g.get("name")] = np.array([float(v) for v in g.get("rgba").split()])
                if g.get("name") in gone:
                    body.remove(g)
        if engine:  # the coordinates, as display-only joints after every other one
            world = root.find("worldbody")
            for fm in modes:
                for k in range(fm.omega.size):
                    b = ET.SubElement(world, "body", name=f"{fm.name}_mode{k + 1}_shown")
                    ET.SubElement(b, "inertial", pos="0 0 0", mass="1e-6", diaginertia="1e-9 1e-9 1e-9")
                    ET.SubElement(b, "joint", name=f"{fm.name}_mode{k + 1}", type="slide", axis="0 0 1")
        deformable = ET.SubElement(root, "deformable")
        # rest vertices in the bone's frame: the warp at q = 0 (the same vertex order as the
        # force engine's and the meshes')
        for fm in modes:
            v = _rest_vertices(fm)
            # dim 2: a surface drawn from both sides (the meshes needed an underside twin)
            f = ET.SubElement(deformable, "flex", name=fm.name, dim="2", radius="0.0002",
                              body=" ".join([fm.body] * len(v)), vertex=_v(v),
                              element=" ".join(str(int(k)) for k in fm.faces.ravel()),
                              rgba=_v(rgba[fm.name]))
            ET.SubElement(f, "contact", contype="0", conaffinity="0")
        self.model = mujoco.MjModel.from_xml_string(ET.tostring(root, encoding="unicode"))
        m = self.model
        if engine:
            shown, ix = dove.drawing()
            nc = sum(fm.omega.size for fm in modes)
            if m.nq != shown.nq + nc:
                raise ModelError("the feather drawing model does not match the dove's drawing model")
            self.ix = np.concatenate([ix, dove.model.nq + np.arange(nc)])
        else:
            if m.nq != dove.model.nq or not np.array_equal(m.jnt_qposadr, dove.model.jnt_qposadr) \
                    or not np.array_equal(m.body_mass, dove.model.body_mass):
                raise ModelError("the feather drawing model does not match the dove's qpos layout "
                                 "(a dove not built by Dove.load(feathers='modal'))")
            self.ix = np.arange(dove.model.nq)
        """``frame[ix]`` is this model's ``qpos``
        (:meth:`~flapsim.bird.flight.dove_flight.DoveFlight.frame`)."""
        self.modal = ModalFeathers(m, modes, _drawing_table(), 1.0)
        self.vertadr = np.array([m.flex_vertadr[mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_FLEX, fm.name)]
                                 for fm in modes])

    def apply(self, data: mujoco.MjData) -> None:
        """Write the deformed feathers of the state in ``data.qpos`` into the model's flex
        vertices; ``mj_forward`` (or ``mj_flex`` after it) then places them."""
        md, K, vert = self.modal, self.modal.K, self.model.flex_vert
        for i, a in enumerate(self.vertadr):
            q0 = md.qadr[i]
            v = md.body_vertices(data.qpos[q0:q0 + K], i)
            vert[a:a + len(v)] = v

    def before_frame(self, data: mujoco.MjData, renderer: object = None) -> None:
        """The ``before_frame`` hook of :func:`flapsim.render.video.render_video` (it runs after
        the frame's ``mj_forward``): deform, then place the flex vertices again."""
        self.apply(data)
        mujoco.mj_flex(self.model, data)


def _rest_vertices(fm: FeatherModes) -> np.ndarray:
    """The feather's vertices warped at zero coordinates (the force engine's vertex order)."""
    K = fm.omega.size
    ff = np.concatenate([fm.root, fm.shaft, fm.chord, fm.normal, [fm.length], fm.gamma,
                         fm.first_moment.ravel()])
    grid = np.ascontiguousarray(np.stack([fm.slope, fm.twist], axis=-1).ravel())
    nv = len(fm.vert_x)
    wo = nv * 3 * (1 + K)
    out = np.zeros(wo + (6 + 6 * K) * fm.stations + 3 * K)
    warp(K, ff, 0, grid, 0, fm.stations, fm.sub, np.zeros(K), np.ascontiguousarray(fm.vert_station, np.int64),
         np.ascontiguousarray(fm.vert_x, float), 0, nv, out, wo)
    return out[:wo].reshape(nv, 1 + K, 3)[:, 0, :].copy()


def _drawing_table() -> CoefficientTable:
    return get_table("flat_plate")  # only the geometry (the warp) is used: any table


def video_model(dove) -> tuple[mujoco.MjModel, object, np.ndarray]:
    """The rendering model of a modal dove, the ``before_frame`` hook of
    :func:`flapsim.render.video.render_video` that draws its feathers bent (:class:`FeatherDrawing`)
    and the index array ``ix`` that turns a flight's frames into its ``qpos``."""
    draw = FeatherDrawing(dove)
    return draw.model, draw.before_frame, draw.ix
