"""flapsim: animals moving through air and water in MuJoCo.

Three systems on one engine: data-driven flapping flight (``flapsim.bird``), layered
swimming (``flapsim.swim``) and modal locomotion (``flapsim.modal``), sharing the
passive-force dispatcher (``flapsim.core``) and the surface/buoyancy force engine
(``flapsim.fluid``).

Importing flapsim changes no environment variable. MuJoCo picks its GL backend when it is
first imported: for offscreen videos without a display set ``MUJOCO_GL=egl`` before
importing flapsim (the ``flapsim`` command does this itself).
"""

__version__ = "0.1.0"
