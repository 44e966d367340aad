"""The one sky, ground and light of flapsim's pictures: a sky gradient, grass with a grid for
scale and a sun casting shadows under a dim headlight. The dove's drawing model wears them
(:mod:`flapsim.bird.body.plumage`); any other MJCF model, a modal creature's or a user's, gets
them from :func:`drawing_model`, a copy compiled for the picture only (its simulation never
sees it: same bodies, joints and ``nq``, so its ``qpos`` frames draw as they are)."""

from __future__ import annotations

import os
from pathlib import Path

import mujoco
import numpy as np

from flapsim.core.callbacks import DISPATCHER
from flapsim.core.errors import ModelError

SKY_RGB = ((0.42, 0.62, 0.88), (0.93, 0.96, 1.0))
"""The sky gradient: overhead, then toward the horizon (RGB 0-1)."""
GRASS_RGB = ((0.40, 0.55, 0.30), (0.36, 0.50, 0.27))
"""The ground's two checker greens (RGB 0-1)."""
GRID_LINE_RGB = (0.28, 0.36, 0.22)
"""The grid lines on the squares' edges (RGB 0-1)."""
SUN_DIR = (-0.3, 0.25, -1.0)
"""Where the sunlight goes (world, unnormalized): from above, a little from behind and the right."""
SUN_DIFFUSE = (0.75, 0.73, 0.68)
HEADLIGHT = {"ambient": (0.25, 0.25, 0.25), "diffuse": (0.35, 0.35, 0.35),
             "specular": (0.05, 0.05, 0.05)}
"""A dim headlight: the sun's shading and shadows carry the shape."""
SHADOW_SIZE = 4096
"""Shadow map side, texels: soft enough edges at video sizes."""


def _rgb(v) -> str:
    return " ".join(f"{x:g}" for x in v)


def sky_xml() -> dict[str, str]:
    """The sky texture's MJCF attributes (builtin gradient): for an MJCF written as text."""
    return {"builtin": "gradient", "rgb1": _rgb(SKY_RGB[0]), "rgb2": _rgb(SKY_RGB[1])}


def grass_xml() -> dict[str, str]:
    """The ground texture's MJCF attributes (builtin checker with edge marks)."""
    return {"builtin": "checker", "rgb1": _rgb(GRASS_RGB[0]), "rgb2": _rgb(GRASS_RGB[1]),
            "mark": "edge", "markrgb": _rgb(GRID_LINE_RGB), "width": "256", "height": "256"}


def dress_spec(spec: mujoco.MjSpec, grid_m: float = 2.0, width: int = 640,
               height: int = 480) -> None:
    """Give ``spec`` the sky, grass (each checker square ``grid_m`` metres, on every plane of
    the world body), the sun and the headlight, and an offscreen buffer of at least
    ``width`` x ``height``. Adds textures, a material and a light: no body, joint or DOF."""
    sky = spec.add_texture(name="flapsim_sky", type=mujoco.mjtTexture.mjTEXTURE_SKYBOX,
                           builtin=mujoco.mjtBuiltin.mjBUILTIN_GRADIENT, width=512, height=512)
    sky.rgb1, sky.rgb2 = SKY_RGB
    grass = spec.add_texture(name="flapsim_grass", type=mujoco.mjtTexture.mjTEXTURE_2D,
                             builtin=mujoco.mjtBuiltin.mjBUILTIN_CHECKER,
                             mark=mujoco.mjtMark.mjMARK_EDGE, width=256, height=256)
    grass.rgb1, grass.rgb2 = GRASS_RGB
    grass.markrgb = GRID_LINE_RGB
    mat = spec.add_material(name="flapsim_grass", texuniform=True, reflectance=0.0)
    mat.textures[mujoco.mjtTextureRole.mjTEXROLE_RGB] = "flapsim_grass"
    # texuniform: the texture repeats per metre of the plane; each repeat holds 2 x 2 squares
    mat.texrepeat = (0.5 / grid_m, 0.5 / grid_m)
    for g in spec.worldbody.geoms:
        if g.type == mujoco.mjtGeom.mjGEOM_PLANE:
            g.material = "flapsim_grass"
            g.rgba = (1.0, 1.0, 1.0, 1.0)
    for light in spec.worldbody.lights:
        light.castshadow = False  # one sun
        light.diffuse = 0.4 * np.asarray(light.diffuse)
    sun = spec.worldbody.add_light(name="flapsim_sun", type=mujoco.mjtLightType.mjLIGHT_DIRECTIONAL,
                                   castshadow=True, pos=(0.0, 0.0, 50.0))
    sun.dir = SUN_DIR
    sun.diffuse = SUN_DIFFUSE
    sun.specular = (0.2, 0.2, 0.2)
    head = spec.visual.headlight
    head.ambient, head.diffuse, head.specular = (HEADLIGHT[k] for k in ("ambient", "diffuse",
                                                                         "specular"))
    spec.visual.quality.shadowsize = SHADOW_SIZE
    g = spec.visual.global_
    g.offwidth, g.offheight = max(int(g.offwidth), int(width)), max(int(g.offheight), int(height))


def drawing_model(source: str | os.PathLike, nq: int | None = None, grid_m: float = 2.0,
                  width: int = 640, height: int = 480) -> mujoco.MjModel:
    """The MJCF file ``source`` compiled for pictures (:func:`dress_spec`). ``nq``: the model
    the frames come from has this many positions (checked: a one-line
    :class:`~flapsim.core.errors.ModelError` otherwise)."""
    path = Path(source)
    with DISPATCHER.suspended():  # MuJoCo refuses to compile while a Python callback is set
        try:
            spec = mujoco.MjSpec.from_file(str(path))
            dress_spec(spec, grid_m, width, height)
            for i, body in enumerate(spec.worldbody.bodies):
                if not body.name:  # a camera follows a body by name
                    body.name = f"flapsim_root{i}"
            model = spec.compile()
        except ValueError as exc:
            reason = " ".join(str(exc).split())
            raise ModelError(f"cannot draw {path}: {reason} (fix the MJCF and retry)") from None
    if nq is not None and model.nq != nq:
        raise ModelError(f"{path} has {model.nq} positions but the frames {nq}: draw the model "
                         "the frames were recorded with")
    return model
