"""Lift and drag coefficient tables over the full 0-180 deg angle-of-attack range.

Convention (the usual one for a wing section turned through 180 deg): ``aoa`` is the
angle between the relative flow and the plate's chord line, 0 deg when the flow comes
from the leading edge along the chord, 180 deg when it comes from the trailing edge.
For a plate symmetric about its chord the lift coefficient is odd about 90 deg,
``CL(180 - a) = -CL(a)``, and drag is even, ``CD(180 - a) = CD(a)``. How the engine
orients lift for each half is described in :mod:`flapsim.fluid.surfaces`.

Every table is sampled on a uniform 0.5 deg grid (361 samples) so the compiled kernel
interpolates it without a search.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from flapsim.core.errors import InputError

N_SAMPLES = 361
AOA_DEG = np.linspace(0.0, 180.0, N_SAMPLES)
_A = np.deg2rad(AOA_DEG)


@dataclass(frozen=True)
class CoefficientTable:
    """CL and CD sampled on :data:`AOA_DEG` (0..180 deg, 0.5 deg apart)."""

    name: str
    #: lift coefficient at each grid angle (dimensionless, referenced to polygon area)
    cl: np.ndarray = field(repr=False)
    #: drag coefficient at each grid angle (dimensionless, referenced to polygon area)
    cd: np.ndarray = field(repr=False)
    #: where the numbers come from
    source: str = ""

    def __post_init__(self) -> None:
        for label, arr in (("cl", self.cl), ("cd", self.cd)):
            a = np.asarray(arr, dtype=float)
            if a.shape != (N_SAMPLES,) or not np.all(np.isfinite(a)):
                raise InputError(f"table {self.name}: {label} must be {N_SAMPLES} finite samples")
            object.__setattr__(self, label, a)
        if np.any(self.cd < 0):
            raise InputError(f"table {self.name}: drag coefficients must be >= 0")

    def at(self, aoa_deg: np.ndarray | float) -> tuple[np.ndarray, np.ndarray]:
        """(CL, CD) at angles in degrees (linear interpolation; the kernel does the same)."""
        a = np.clip(np.asarray(aoa_deg, dtype=float), 0.0, 180.0)
        return np.interp(a, AOA_DEG, self.cl), np.interp(a, AOA_DEG, self.cd)

    @classmethod
    def from_samples(
        cls, name: str, aoa_deg: np.ndarray, cl: np.ndarray, cd: np.ndarray, source: str = ""
    ) -> CoefficientTable:
        """Resample measured points (any increasing 0..180 grid) onto the standard grid."""
        aoa_deg = np.asarray(aoa_deg, dtype=float)
        if aoa_deg.ndim != 1 or aoa_deg[0] > 0 or aoa_deg[-1] < 180 or np.any(np.diff(aoa_deg) <= 0):
            raise InputError(f"table {name}: angles must increase and cover 0..180 deg")
        return cls(name, np.interp(AOA_DEG, aoa_deg, cl), np.interp(AOA_DEG, aoa_deg, cd), source)


def _mirror(cl_0_90: np.ndarray, cd_0_90: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Extend values given on 0..90 deg (first 181 samples) to 0..180 by plate symmetry."""
    half = (N_SAMPLES + 1) // 2
    cl = np.empty(N_SAMPLES)
    cd = np.empty(N_SAMPLES)
    cl[:half] = cl_0_90[:half]
    cd[:half] = cd_0_90[:half]
    cl[half:] = -cl[: half - 1][::-1]
    cd[half:] = cd[: half - 1][::-1]
    cl[half - 1] = 0.0  # lift vanishes with flow normal to a symmetric plate
    return cl, cd


def flat_plate(cd0: float = 0.02) -> CoefficientTable:
    """Post-stall flat plate, normal-force model: CN = 2 sin a, CL = 2 sin a cos a,
    CD = 2 sin^2 a + cd0 (REFERENCE_DATA 'Lift and drag coefficients')."""
    return CoefficientTable(
        "flat_plate",
        2.0 * np.sin(_A) * np.cos(_A),
        2.0 * np.sin(_A) ** 2 + cd0,
        "flat plate normal-force model CN = 2 sin a (Hoerner 1965; Dickinson et al. 1999 Fig. 3)",
    )


def feather_stall(
    lift_slope: float = 4.0, stall_deg: float = 14.0, cd0: float = 0.05, blend_deg: float = 4.0
) -> CoefficientTable:
    """Attached flow up to stall, then the flat plate.

    Below ``stall_deg`` CL = ``lift_slope`` * a (4/rad: a low-aspect-ratio wing), CD =
    cd0 + 2 sin^2 a; above it the flat-plate model; blended linearly over ``blend_deg``
    past the stall angle so the table stays continuous. Defaults give CL max ~1.0 and
    a drag floor 0.05, inside the bird-wing ranges of Withers 1981 (max CL 0.8-1.2,
    min CD 0.03-0.13).
    """
    a = _A
    attached = lift_slope * a
    plate_cl = 2.0 * np.sin(a) * np.cos(a)
    s0, s1 = np.deg2rad(stall_deg), np.deg2rad(stall_deg + blend_deg)
    t = np.clip((a - s0) / (s1 - s0), 0.0, 1.0)
    cl = (1 - t) * attached + t * plate_cl
    cd = cd0 + 2.0 * np.sin(a) ** 2
    cl, cd = _mirror(cl, cd)
    return CoefficientTable(
        "feather_stall",
        cl,
        cd,
        f"attached lift slope {lift_slope}/rad, stall {stall_deg} deg, then flat plate; "
        "ranges from Withers 1981 JEB 90:143",
    )


def _taper_ends(values: np.ndarray, width_deg: float = 10.0) -> np.ndarray:
    """Remove a fit's offsets at 0 and 90 deg over ``width_deg`` so that lift vanishes
    where a symmetric plate has none (keeps the mirrored table continuous)."""
    a = AOA_DEG[: (N_SAMPLES + 1) // 2]
    out = values.copy()
    out -= values[0] * np.clip(1.0 - a / width_deg, 0.0, 1.0)
    out -= values[-1] * np.clip(1.0 - (90.0 - a) / width_deg, 0.0, 1.0)
    return out


def dickinson1999(cd0: float | None = None) -> CoefficientTable:
    """Quasi-steady flapping-wing coefficients of the robofly (Dickinson, Lehmann & Sane
    1999, Science 284:1954; Re ~ 10^2), which fold in the leading-edge vortex:
    CL = 0.225 + 1.58 sin(2.13 a - 7.20 deg), CD = 1.92 - 1.55 cos(2.04 a - 9.82 deg).

    The fit's small lift offsets at 0 and 90 deg (0.03, 0.10) are tapered to zero within
    10 deg so the 0..180 table is continuous; the peak (CL 1.8 near 45 deg) is untouched.
    ``cd0`` (optional) shifts the WHOLE drag curve down by ``CD(0) - cd0`` so that
    CD(0) = cd0: the robofly's 0.39 is high for a feathered wing (REFERENCE_DATA; bird
    wings 0.03-0.13, Withers 1981). This is ``dickinson1999_lowdrag`` (cd0 = 0.05): CD is
    Dickinson's minus 0.343 at EVERY angle, including the separated-flow angles where the
    drag is pressure drag that the Reynolds number does not lower (at 90 deg: 3.46 -> 3.12,
    while CL is unchanged), so that table also lowers the drag of the stalled wing, which
    no measurement supports. :func:`dickinson1999_profile` lowers only the viscous part.
    """
    half = (N_SAMPLES + 1) // 2
    a_deg = AOA_DEG[:half]
    cl = 0.225 + 1.58 * np.sin(np.deg2rad(2.13 * a_deg - 7.20))
    cd = 1.92 - 1.55 * np.cos(np.deg2rad(2.04 * a_deg - 9.82))
    cl = _taper_ends(cl)
    name = "dickinson1999"
    if cd0 is not None:
        cd = cd - cd[0] + cd0
        name = f"dickinson1999_cd0_{cd0:g}"
    full_cl, full_cd = _mirror(np.concatenate([cl, np.zeros(half - 1)]),
                               np.concatenate([cd, np.zeros(half - 1)]))
    return CoefficientTable(
        name, full_cl, full_cd, "Dickinson, Lehmann & Sane 1999, Science 284:1954 (robofly fit)"
    )


def dickinson1999_profile(cd0: float = 0.05) -> CoefficientTable:
    """The Dickinson 1999 fit with a bird wing's profile drag at low angle of attack and the
    fit itself at high angle of attack.

    The robofly's drag splits into a normal-force (pressure) part, ``CL tan a`` (the lift
    and drag of a force normal to the plate), which does not depend on Reynolds number,
    and a viscous remainder ``v(a) = CD(a) - CL(a) tan a``: 0.39 at 0 deg, 0.29 at 10,
    0.18 at 20, 0.06 at 30 and none from 35.5 deg on. Only the viscous part belongs to the
    robofly's Re ~ 10^2; at a bird wing's Re (1e4-5e4) it is the profile drag, 0.03-0.13
    at zero lift (Withers 1981, J Exp Biol 90:143). So the viscous part is scaled by
    ``cd0 / v(0)``: ``CD = CL tan a + v(a) cd0 / v(0)`` where ``v > 0``, and ``CD`` equals
    Dickinson's wherever ``v <= 0`` (from 35.5 deg up). CL is Dickinson's unchanged. At
    0/10/20/30 deg: 0.05 / 0.144 / 0.43 / 0.90 against Dickinson's 0.39 / 0.40 / 0.59 / 0.95
    (``dickinson1999_lowdrag``: 0.05 / 0.05 / 0.25 / 0.61, shifted everywhere).
    """
    base = dickinson1999()
    half = (N_SAMPLES + 1) // 2
    a = _A[:half]
    cl, cd = base.cl[:half], base.cd[:half]
    pressure = np.zeros(half)
    inner = a < np.deg2rad(60.0)  # tan a stays finite; v turns negative at 35.5 deg anyway
    pressure[inner] = cl[inner] * np.tan(a[inner])
    viscous = cd - pressure
    # the viscous part's first sign change ends the blend: from there on, pure Dickinson
    stop = int(np.argmax(viscous <= 0.0))
    w = np.zeros(half)
    w[:stop] = viscous[:stop] / viscous[0]
    cd_new = cd - (viscous[0] - cd0) * w
    full_cl, full_cd = _mirror(cl, cd_new)
    return CoefficientTable(
        "dickinson1999_profile" if cd0 == 0.05 else f"dickinson1999_profile_cd0_{cd0:g}",
        full_cl, full_cd,
        "Dickinson, Lehmann & Sane 1999 (robofly fit); viscous part scaled to bird-wing "
        f"profile drag CD0 = {cd0:g} (Withers 1981 JEB 90:143: 0.03-0.13)",
    )


def bluff_body(cd: float = 0.3) -> CoefficientTable:
    """A bluff body's cross-section: no lift, drag ``cd sin a`` on the section's area.

    ``a`` is the angle between the flow and the section's plane, so flow square to the
    section (a = 90 deg) gives the full ``cd`` on its area, flow along it nothing. Three
    orthogonal cross-sections of a body (areas A_x, A_y, A_z) then give drag
    ``1/2 rho V^2 cd (A_x |u_x| + A_y |u_y| + A_z |u_z|)`` for a flow direction ``u``: exact
    head-on, and within +41% (flow at 45 deg between two equal sections) of the projected
    area ``sqrt(sum (A_i u_i)^2)`` in between. Bird bodies: cd 0.2-0.4 on the frontal
    area (frozen bodies in a wind tunnel, Pennycuick, Obrecht & Fuller 1988, J Exp Biol
    135:253; Tucker 1990, J Exp Biol 149:449).
    """
    if not (np.isfinite(cd) and cd >= 0):
        raise InputError(f"bluff-body drag coefficient must be >= 0, got {cd}")
    return CoefficientTable(
        "bluff_body" if cd == 0.3 else f"bluff_body_cd_{cd:g}",
        np.zeros(N_SAMPLES), cd * np.abs(np.sin(_A)),
        "bluff-body drag on cross-sections (Pennycuick et al. 1988 JEB 135:253; Tucker 1990)",
    )


def wang2004() -> CoefficientTable:
    """Wang, Birch & Dickinson 2004 (JEB 207:449): CL = 1.2 sin 2a, CD = 1.4 - cos 2a."""
    return CoefficientTable(
        "wang2004", 1.2 * np.sin(2 * _A), 1.4 - np.cos(2 * _A), "Wang, Birch & Dickinson 2004"
    )


def hoerner_plate(aspect_ratio: float = 0.2, cd_crossflow: float = 1.2, cd0: float = 0.0
                  ) -> CoefficientTable:
    """Thin low-aspect-ratio plate fully immersed at low Reynolds number (the swimming
    paper's Fig. 5 model, after Hoerner 1965 / Hoerner & Borst 1975).

    Normal force CN = (pi/2) AR sin a cos a + CDc sin^2 a (slender-wing lift slope plus
    cross-flow drag), CL = CN cos a, CD = CN sin a + cd0. CDc = 1.2 is Hoerner's normal
    drag of a 5:1 rectangular plate (1.17 square .. 1.98 two-dimensional). With AR 0.2 this
    peaks at CL ~0.56 near 50 deg and CD 1.2 at 90 deg, matching hand/forearm data
    (Berger et al. 1995: max CL 0.5-0.6, max CD 1.1-1.2). Skin friction is the engine's
    separate eta*A*v_t term, so cd0 defaults to 0.
    """
    if aspect_ratio <= 0:
        raise InputError("aspect_ratio must be > 0")
    a = _A
    cn = 0.5 * np.pi * aspect_ratio * np.sin(a) * np.cos(a) + cd_crossflow * np.sin(a) ** 2
    cl, cd = _mirror(cn * np.cos(a), cn * np.sin(a) + cd0)
    return CoefficientTable(
        f"hoerner_plate_ar{aspect_ratio:g}",
        cl,
        cd,
        "Hoerner 1965 Fluid-Dynamic Drag; Hoerner & Borst 1975 Fluid-Dynamic Lift (low-AR plate)",
    )


def rounded_surface(cp_stagnation: float = 1.0) -> CoefficientTable:
    """A patch of a rounded body's surface (Newtonian impact theory): the water that meets
    the patch at angle ``a`` presses on it along its normal with ``Cp = C sin^2 a``, so
    CN = C sin^2 a, CL = CN cos a, CD = CN sin a (the engine takes drag along the flow and
    lift across it). ``C`` is the stagnation pressure coefficient: 1 is the exact
    incompressible value, and then a surface of such patches in a uniform stream sums to a
    sphere's CD = 1/2 (measured 0.47 subcritical, Hoerner 1965) and a circular cylinder's
    in cross flow to 2/3; C = 1.8 gives the cylinder its measured 1.2 (Hoerner 1965, Re
    1e4-2e5, the wake's suction folded into the front). Rear-facing patches are the
    engine's ``front_facing_only`` rule; skin friction its separate ``eta A v_t``.
    """
    if not (np.isfinite(cp_stagnation) and cp_stagnation > 0):
        raise InputError(f"stagnation pressure coefficient must be > 0, got {cp_stagnation}")
    a = _A
    cn = cp_stagnation * np.sin(a) ** 2
    cl, cd = _mirror(cn * np.cos(a), cn * np.sin(a))
    return CoefficientTable(
        "rounded_surface" if cp_stagnation == 1.0 else f"rounded_surface_cp_{cp_stagnation:g}",
        cl, cd,
        "Newtonian surface pressure C sin^2 a; sphere CD 0.47, cylinder in cross flow 1.0-1.2 "
        "(Hoerner 1965 Fluid-Dynamic Drag)",
    )


#: Revolving rock-dove and pigeon wings (the bird's own wings, spun at in-vivo Reynolds
#: numbers): Usherwood 2009 (Exp Fluids 46:991, pigeon wing, CL max 1.64 near 43 deg) and
#: Crandell & Tobalske 2011 (J Exp Biol 214:1867, rock-dove wings: L/D 3.33 at the 46 deg of
#: mid-downstroke, 0.91 at the 66 deg of mid-upstroke, peak 6.3).
DOVE_CL_MAX = 1.64
DOVE_LD_46 = 3.33


def dove_revolving(cd0: float = 0.05) -> CoefficientTable:
    """Coefficients fitted to revolving dove and pigeon wings (see :data:`DOVE_CL_MAX`).

    The robofly's (and so :func:`dickinson1999_profile`'s) force at high angle of attack is
    nearly normal to the plate: L/D 1.03 at 46 deg (cot 46 deg = 0.97), where a real dove
    wing gives 3.33.
    Here CL is Dickinson's curve scaled to the pigeon wing's peak (1.64), and CD is a drag
    polar ``cd0 + k CL^2`` up to 46 deg (``cd0``: profile drag, Withers 1981: 0.03-0.13;
    ``k`` makes L/D 3.33 at 46 deg, i.e. an efficiency factor of ~0.3 for the dove's aspect
    ratio, within Withers's 0.2-0.8), blended linearly in angle into the scaled normal-force
    drag of :func:`dickinson1999_profile` at 90 deg. Checks against the data not fitted:
    L/D 0.94 at 66 deg (Crandell & Tobalske: 0.91 for the upstroke wing) and a peak L/D of
    5.5 at 10 deg (6.3). NOT the default (see docs/flight.md, "Flapping flight (the dove)"):
    with it the reference wingbeat out-pulls its drag by ~0.28 of the weight.
    """
    base = dickinson1999_profile(cd0)
    half = (N_SAMPLES + 1) // 2
    a = AOA_DEG[:half]
    s = DOVE_CL_MAX / float(base.cl[:half].max())
    cl = s * base.cl[:half]
    i46 = int(np.argmin(np.abs(a - 46.0)))
    k = (cl[i46] / DOVE_LD_46 - cd0) / cl[i46] ** 2
    w = np.clip((a - 46.0) / 44.0, 0.0, 1.0)
    cd = (1.0 - w) * (cd0 + k * cl**2) + w * s * base.cd[:half]
    full_cl, full_cd = _mirror(cl, cd)
    return CoefficientTable(
        "dove_revolving" if cd0 == 0.05 else f"dove_revolving_cd0_{cd0:g}", full_cl, full_cd,
        "Dickinson 1999 CL shape scaled to CL max 1.64 (Usherwood 2009 Exp Fluids 46:991); "
        f"drag polar CD0 {cd0:g} + k CL^2 with L/D 3.33 at 46 deg (Crandell & Tobalske 2011 "
        "J Exp Biol 214:1867), blended into normal-force drag at 90 deg",
    )


#: A spread bird wing's attached-flow section, gliding (Tucker & Heine 1990, J Exp Biol
#: 149:469, Harris hawk): lift slope, static CL max and profile drag at CL 0.6. The slope is
#: thin-aerofoil 2 pi reduced by 0.8 for a feathered section at Re ~ 3e4 (the same factor as
#: the reference data's attached polar; Withers 1981, J Exp Biol 90:143: bird-wing sections
#: reach CL 0.8-1.6 within 15-20 deg).
BIRD_LIFT_SLOPE = 2.0 * np.pi * 0.8
BIRD_CL_MAX_STATIC = 1.5
BIRD_PROFILE_CD_AT_CL06 = 0.03
BIRD_PROFILE_CD0 = 0.02


def bird_wing(blend_end_deg: float = 30.0) -> CoefficientTable:
    """A bird wing's section: attached flow to its stall, then the revolving dove wing.

    Up to the stall, CL = :data:`BIRD_LIFT_SLOPE` a, reaching :data:`BIRD_CL_MAX_STATIC` (1.5,
    Tucker & Heine's 1.4-1.6) at 17.1 deg, with a profile drag polar ``CD0 + kp CL^2``:
    :data:`BIRD_PROFILE_CD0` (0.02) at zero lift and :data:`BIRD_PROFILE_CD_AT_CL06` (0.03,
    Tucker & Heine) at CL 0.6. This is the section's own drag: the wing's induced drag is
    not in the table (a quasi-steady table that folds it in, as the revolving-wing fits do,
    would count it again where the engine models the wake's downwash). Past the stall the
    lift and drag blend linearly in angle into :func:`dove_revolving` by ``blend_end_deg``
    and follow it from there: the leading-edge-vortex plateau of revolving dove and pigeon
    wings (CL max 1.64 near 45 deg, Usherwood 2009, Exp Fluids 46:991; L/D 3.33 at the
    46 deg of mid-downstroke, Crandell & Tobalske 2011, J Exp Biol 214:1867), and normal-force
    drag at 90 deg. The section is symmetric (no camber): CL is odd about 90 deg, as for every
    table here. The robofly fits (:func:`dickinson1999_profile`, Re ~ 10^2) give CD 0.05-0.4
    at zero lift; a bird wing's section at Re ~ 3e4 is 2.5-20x cleaner there.
    """
    half = (N_SAMPLES + 1) // 2
    a = _A[:half]
    a_deg = AOA_DEG[:half]
    stall_deg = float(np.rad2deg(BIRD_CL_MAX_STATIC / BIRD_LIFT_SLOPE))
    if not stall_deg < blend_end_deg <= 60.0:
        raise InputError(f"bird_wing: blend_end_deg must be in ({stall_deg:.1f}, 60] deg, "
                         f"got {blend_end_deg}")
    kp = (BIRD_PROFILE_CD_AT_CL06 - BIRD_PROFILE_CD0) / 0.6**2
    cl_att = BIRD_LIFT_SLOPE * a
    cd_att = BIRD_PROFILE_CD0 + kp * cl_att**2
    rev = dove_revolving()
    t = np.clip((a_deg - stall_deg) / (blend_end_deg - stall_deg), 0.0, 1.0)
    at_stall = min(int(np.searchsorted(a_deg, stall_deg)), half - 1)
    # past the stall the attached line is held at its stall value while it blends away
    cl_hold = np.where(a_deg <= stall_deg, cl_att, cl_att[at_stall])
    cd_hold = np.where(a_deg <= stall_deg, cd_att, cd_att[at_stall])
    cl = (1.0 - t) * cl_hold + t * rev.cl[:half]
    cd = (1.0 - t) * cd_hold + t * rev.cd[:half]
    full_cl, full_cd = _mirror(cl, cd)
    return CoefficientTable(
        "bird_wing" if blend_end_deg == 30.0 else f"bird_wing_blend_{blend_end_deg:g}",
        full_cl, full_cd,
        f"attached lift {BIRD_LIFT_SLOPE:.2f}/rad to CL {BIRD_CL_MAX_STATIC} at {stall_deg:.1f} deg, "
        f"profile drag {BIRD_PROFILE_CD0} + {kp:.4f} CL^2 (Tucker & Heine 1990 J Exp Biol 149:469); "
        f"blended by {blend_end_deg:g} deg into dove_revolving (Usherwood 2009; Crandell & "
        "Tobalske 2011)",
    )


TABLES: dict[str, Callable[[], CoefficientTable]] = {
    "flat_plate": flat_plate,
    "feather_stall": feather_stall,
    "dickinson1999": dickinson1999,
    "dickinson1999_lowdrag": lambda: dickinson1999(cd0=0.05),
    "dickinson1999_profile": dickinson1999_profile,
    "dove_revolving": dove_revolving,
    "bird_wing": bird_wing,
    "bluff_body": bluff_body,
    "wang2004": wang2004,
    "hoerner_plate": hoerner_plate,
    "rounded_surface": rounded_surface,
}


def get_table(name: str | CoefficientTable) -> CoefficientTable:
    """A table by name (see :data:`TABLES`), or the table itself."""
    if isinstance(name, CoefficientTable):
        return name
    if name not in TABLES:
        raise InputError(f"unknown coefficient table {name!r}; choose one of {', '.join(TABLES)}")
    return TABLES[name]()
