"""Modal feathers are drawn bent: the videos' drawing (flexes on the bones, their vertices
from the warp) against the imposed modal deflection, a rendered frame, and the viewer's
per-frame drawing during a flight."""

import contextlib
import copy
import types

import mujoco
import numpy as np
import pytest

from flapsim.bird.body.drawing import FeatherDrawing, video_model
from flapsim.bird.body.feather_dynamics import ModalFeathers, dove_feather_modes
from flapsim.bird.body.model import Dove
from flapsim.bird.body.params import UNDERSIDE
from flapsim.fluid.coefficients import get_table

FEATHER = "l_p8"
DEFLECTION = 0.02  # m: the largest vertex deflection of the rendered bend (P8 is 0.127 m long)
ROTATION = 0.15  # rad: the largest section slope or twist imposed in the geometric check


@pytest.fixture(scope="module")
def dove():
    return Dove.load(feathers="modal")


@pytest.fixture(scope="module")
def drawing(dove):
    return FeatherDrawing(dove)


def _mesh_vertices_world(m: mujoco.MjModel, d: mujoco.MjData, geom: str) -> np.ndarray:
    """The undeformed feather as the physics model's mesh geom places it (world frame)."""
    g = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, geom)
    mid = m.geom_dataid[g]
    v = m.mesh_vert[m.mesh_vertadr[mid]:m.mesh_vertadr[mid] + m.mesh_vertnum[mid]].astype(float)
    return d.geom_xpos[g] + v @ d.geom_xmat[g].reshape(3, 3).T


def _engine(dove) -> ModalFeathers:
    """The dove's own modal feathers (forces and warp), on its twist hinges."""
    return ModalFeathers(dove.model, dove_feather_modes(dove.params, dove.modal),
                         get_table("flat_plate"), 1.0, hinges=dove.twist_hinges(), params=dove.modal)


def _bent_state(dove, drawing, k: int = 0) -> tuple[np.ndarray, int, float]:
    """The modal coordinates (n_feathers, K), all zero but mode ``k`` of FEATHER, set so
    that its largest section rotation (shaft slope or twist) is ROTATION; returns
    (coordinates, feather index, coordinate)."""
    i = drawing.modal.feather_index(FEATHER)
    fm = drawing.modal.modes[i]
    q = ROTATION / max(np.max(np.abs(fm.slope[:, k])), np.max(np.abs(fm.twist[:, k])))
    coords = np.zeros((len(drawing.modal.modes), drawing.modal.K))
    coords[i, k] = q
    return coords, i, q


def _frame(dove, coords: np.ndarray) -> np.ndarray:
    """A flight frame (DoveFlight.frame): the dove's rest qpos, then the coordinates."""
    return np.concatenate([dove.model.qpos0, coords.ravel()])


def test_drawn_feathers_follow_the_imposed_modal_deflection(dove, drawing):
    m = drawing.model
    assert not any(mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_GEOM, g) in (FEATHER, FEATHER + UNDERSIDE)
                   for g in range(m.ngeom)), "the rigid feather meshes would hide the bent ones"
    model, hook, ix = video_model(dove)  # what dove_video draws
    assert model.nflex == len(dove_feather_modes(dove.params, dove.modal))
    d, dp = mujoco.MjData(model), mujoco.MjData(dove.model)
    eng = _engine(dove)
    for k in range(drawing.modal.K):  # bending and twisting modes
        coords, i, q = _bent_state(dove, drawing, k)
        d.qpos[:] = _frame(dove, coords)[ix]
        mujoco.mj_forward(model, d)
        hook(d, None)
        mujoco.mj_forward(dove.model, dp)
        eng.set_coordinates(dp, coords)
        fm = drawing.modal.modes[i]
        a = model.flex_vertadr[mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_FLEX, FEATHER)]
        drawn = d.flexvert_xpos[a:a + len(fm.vert_x)]
        rest = _mesh_vertices_world(dove.model, dp, FEATHER)  # the rigid mesh, same vertex order
        bone = mujoco.mj_name2id(dove.model, mujoco.mjtObj.mjOBJ_BODY, fm.body)
        normal = dp.xmat[bone].reshape(3, 3) @ fm.normal
        # the linear modal deflection q * shape along the feather's normal; modal warping
        # rotates sections instead of shearing them: the normal component differs from the
        # linear one by terms of higher order in the rotations t <= ROTATION, relative
        # t^2 / 6 (sin t = t (1 - t^2 / 6)) and t^2 (bend x twist cross terms)
        lin = q * fm.shape[:, k]
        tol = (ROTATION**2 + ROTATION**2 / 6) * np.abs(lin).max()
        assert (drawn - rest) @ normal == pytest.approx(lin, abs=tol)
        # and it is the force engine's deformed mesh, vertex for vertex
        assert np.allclose(drawn, eng.evaluate(dp).vertices[eng.vert_offset[i]:][:len(fm.vert_x)],
                           atol=1e-9)
        # the other feathers stay where their meshes are
        j = drawing.modal.feather_index("l_s3")
        b = model.flex_vertadr[mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_FLEX, "l_s3")]
        other = d.flexvert_xpos[b:b + len(drawing.modal.modes[j].vert_x)]
        assert np.allclose(other, _mesh_vertices_world(dove.model, dp, "l_s3"), atol=1e-9)


def _render_rest_and_bent(out: str) -> None:
    """Render the rigid dove at rest, the video model at rest and bent (every feather by its
    first mode) and save the three images to ``out`` (.npz)."""
    dove = Dove.load(feathers="modal")
    drawing = FeatherDrawing(dove)
    model, hook, ix = video_model(dove)
    coords = np.zeros((len(drawing.modal.modes), drawing.modal.K))
    for i, fm in enumerate(drawing.modal.modes):
        coords[i, 0] = DEFLECTION / np.max(np.abs(fm.shape[:, 0]))
    qpos = _frame(dove, 0 * coords)[ix]
    bent = _frame(dove, coords)[ix]
    cam = mujoco.MjvCamera()
    d = mujoco.MjData(model)
    d.qpos[:] = qpos
    mujoco.mj_forward(model, d)
    cam.lookat[:] = d.xpos[dove.trunk]
    cam.distance, cam.elevation, cam.azimuth = 0.6, -30.0, 150.0
    # the rigid meshes in the same dress (colours, sky, light), less the white tail tips the
    # bent drawing leaves out (they would not bend with their feathers)
    rigid, rix = dove.drawing()
    rigid = copy.deepcopy(rigid)
    for g in range(rigid.ngeom):
        if (mujoco.mj_id2name(rigid, mujoco.mjtObj.mjOBJ_GEOM, g) or "").endswith("_tip"):
            rigid.geom_rgba[g, 3] = 0.0
    images = []
    for m, q, h in ((rigid, dove.model.qpos0[rix], None), (model, qpos, hook), (model, bent, hook)):
        r = mujoco.Renderer(m, 480, 640)
        try:
            dd = mujoco.MjData(m)
            dd.qpos[:] = q
            mujoco.mj_forward(m, dd)
            if h is not None:
                h(dd, r)
            r.update_scene(dd, cam)
            images.append(r.render().astype(np.int16))
        finally:
            r.close()
    np.savez(out, *images)


def test_a_video_frame_shows_the_bend(tmp_path):
    """dove_video's drawing of a rest frame and of every feather bent by its first mode:
    the rest frame is the rigid meshes' picture, the bent one is not. Rendered in a child
    process: a MuJoCo EGL renderer in the test process would be killed by the next pyvista
    window to close (PITFALLS: the shared EGL display), failing later rendering tests."""
    import os
    import subprocess
    import sys

    pytest.importorskip("imageio")
    out = tmp_path / "frames.npz"
    code = (f"import sys; sys.path.insert(0, {str(os.path.dirname(__file__))!r}); "
            f"import test_drawing as t; t._render_rest_and_bent({str(out)!r})")
    env = {**os.environ, "MUJOCO_GL": os.environ.get("MUJOCO_GL", "egl")}
    run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env,
                         timeout=300)
    assert run.returncode == 0, run.stderr[-2000:]
    with np.load(out) as z:
        images = [z[f"arr_{k}"].astype(int) for k in range(3)]
    rigid, rest, bent_img = images
    changed = lambda a, b: np.any(np.abs(a - b) > 30, axis=-1)  # noqa: E731
    # the flexes rasterize the meshes' triangles (a few hundred edge pixels differ in shading:
    # smooth flex normals); 20 mm tip deflections at 0.6 m on a 480-pixel-high view (fovy 45
    # deg: 1.0 mm a pixel) move each tip ~20 pixels, over ~50 feathers a few pixels wide:
    # thousands of pixels (measured: ~400 and ~9,500)
    assert changed(rigid, rest).sum() < 1500
    assert changed(rest, bent_img).sum() > 4000


@contextlib.contextmanager
def _nolock():
    yield


class _Handle:
    """A stand-in for MuJoCo's passive viewer: records what each frame shows."""

    def __init__(self, model, data, frames: list):
        self.m, self.d, self.frames = model, data, frames
        self.cam = mujoco.MjvCamera()  # the viewer's camera: the chase camera moves it
        self.perturb = mujoco.MjvPerturb()  # the mouse's selection (flapsim.render.viewer reads it)
        self.user_scn = types.SimpleNamespace(ngeom=0, maxgeom=0, geoms=[])

    def lock(self):
        return _nolock()

    def is_running(self) -> bool:
        return len(self.frames) < 6

    def set_texts(self, texts) -> None:
        pass

    def sync(self) -> None:
        self.frames.append((self.m, self.d.qpos.copy(), self.d.flexvert_xpos.copy()))

    def close(self) -> None:
        pass


@pytest.fixture(scope="module")
def modal_db(tmp_path_factory, dove):
    """The bundled database's samples relabelled for the modal dove: the viewer only needs
    a controller it accepts (flight quality is not what is tested here)."""
    from flapsim.bird.control.controller import bundled_database_path
    from flapsim.bird.control.database import load_database, save_database

    db = load_database(bundled_database_path())
    path = tmp_path_factory.mktemp("db") / "modal.db"
    header = {k: v for k, v in db.header.items() if k not in ("fields", "samples")}
    header["model_hash"] = dove.hash()
    save_database(path, header, db.index, db.arrays, db.rejected)
    return path


def test_the_viewer_draws_each_frame_bent(dove, modal_db, monkeypatch):
    from flapsim.bird.tasks.interactive import view_flight
    from flapsim.render import viewer

    # every picture drawn however slowly this machine flies (the viewer drops late ones)
    monkeypatch.setattr(viewer, "MAX_FRAME_GAP_S", 0.0)
    frames: list = []
    r = view_flight(0.3, modal_db, feathers="modal",
                    launch=lambda m, d, **kw: _Handle(m, d, frames))
    assert r["status"] == "window closed" and len(frames) == 6
    eng = _engine(dove)
    ix = FeatherDrawing(dove).ix
    dp = mujoco.MjData(dove.model)
    bend = []
    for m, qpos, drawn in frames:
        assert m.nflex == len(eng.modes)
        frame = np.zeros(len(ix))
        frame[ix] = qpos  # back to the flight's frame: its qpos, then the coordinates
        dp.qpos[:] = frame[:dove.model.nq]
        mujoco.mj_forward(dove.model, dp)
        eng.set_coordinates(dp, frame[dove.model.nq:])
        # what is shown is the frame's own bent feathers (not last frame's, not the rest shape)
        assert np.allclose(drawn, eng.evaluate(dp).vertices, atol=1e-9)
        rest = np.concatenate([_mesh_vertices_world(dove.model, dp, fm.name) for fm in eng.modes])
        bend.append(np.abs(drawn - rest).max())
    # in flight the primaries' tips bend by millimetres (the calibration scene: 1-9 mm)
    assert max(bend) > 5e-4, bend
