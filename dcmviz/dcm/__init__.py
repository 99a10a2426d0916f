"""The paper's equations (Englsberger, Mesesan, Ott): pure numpy, no I/O, no robot."""

from dcmviz.dcm.continuity import continuity_matrix, continuity_waypoints
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
from dcmviz.dcm.preview import PhaseSchedule, Preview

__all__ = [
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
