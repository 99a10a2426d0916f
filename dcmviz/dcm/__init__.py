"""The paper's equations (Englsberger, Mesesan, Ott): pure numpy, no I/O, no robot."""

from dcmviz.dcm.adjustment import (
    adaptation_factor,
    adjusted_waypoints,
    adjustment_gain,
    dcm_adjustment,
    step_adjustment,
)
from dcmviz.dcm.continuity import continuity_matrix, continuity_waypoints
from dcmviz.dcm.control import (
    com_force,
    dcm,
    vrp_adjusted,
    vrp_from_force,
    vrp_height,
    vrp_tracking,
)
from dcmviz.dcm.interpolation import (
    ORDERS,
    alpha,
    alpha_0,
    beta,
    beta_0,
    f,
    gamma,
    gamma_0,
    sigma,
)
from dcmviz.dcm.observer import DisturbanceObserver, ShiftRate, moment_shift, reference_shift
from dcmviz.dcm.preview import PhaseSchedule, Preview

__all__ = [
    "DisturbanceObserver",
    "ShiftRate",
    "adaptation_factor",
    "adjusted_waypoints",
    "adjustment_gain",
    "com_force",
    "dcm",
    "dcm_adjustment",
    "moment_shift",
    "reference_shift",
    "step_adjustment",
    "vrp_adjusted",
    "vrp_from_force",
    "vrp_height",
    "vrp_tracking",
    "ORDERS",
    "PhaseSchedule",
    "Preview",
    "alpha",
    "alpha_0",
    "beta",
    "beta_0",
    "continuity_matrix",
    "continuity_waypoints",
    "f",
    "gamma",
    "gamma_0",
    "sigma",
]
