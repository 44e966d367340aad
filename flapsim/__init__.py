"""flapsim: animals moving through air and water in MuJoCo.

Three systems on one engine: data-driven flapping flight (``flapsim.bird``), layered
swimming (``flapsim.swim``) and modal locomotion (``flapsim.modal``), sharing the
passive-force dispatcher (``flapsim.sim``) and the surface/buoyancy force engine
(``flapsim.fluid``).
"""

import os as _os

# MuJoCo picks its GL backend when it is first imported: choose an offscreen one
# unless the user (or a display) says otherwise.
if "MUJOCO_GL" not in _os.environ and not _os.environ.get("DISPLAY"):
    _os.environ["MUJOCO_GL"] = "egl"

__version__ = "0.1.0"
