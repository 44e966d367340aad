"""System 3: modal locomotion (Kry, Reveret, Faure, Cani 2009).

* :mod:`flapsim.modal.analysis`: vibration modes of any MuJoCo model about its rest pose,
  with closed loops and extra constraints (:func:`analyze`, :class:`ModalAnalysis`).
* :mod:`flapsim.modal.dynamic`: the equilibrium-point controller that drives selected
  modes in a dynamic simulation (:class:`ModalController`).
* :mod:`flapsim.modal.creatures`: the loop and linear creatures and their locomotion runs.

Example: the loop creature's lowest elastic modes::
    import mujoco
    from flapsim.core.assets import asset_path
    from flapsim.modal import analyze

    model = mujoco.MjModel.from_xml_path(str(asset_path("creatures", "loop.xml")))
    modes = analyze(model)
    print(modes.freqs_hz[modes.n_rigid:modes.n_rigid + 2])  # Hz
"""

from flapsim.modal.analysis import (
    ExtraConstraint,
    ModalAnalysis,
    analyze,
    fix_body_orientation,
    fix_joint,
    fix_root,
    ground_contact,
    integrate_displacement,
    parse_constraint,
    pin_site,
    rest_pose,
    tangent_difference,
)

__all__ = [
    "ExtraConstraint",
    "ModalAnalysis",
    "analyze",
    "fix_body_orientation",
    "fix_joint",
    "fix_root",
    "ground_contact",
    "integrate_displacement",
    "parse_constraint",
    "pin_site",
    "rest_pose",
    "tangent_difference",
]
