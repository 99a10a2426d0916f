"""dcmviz: DCM-based humanoid walking (Englsberger, Mesesan, Ott) you can tune in the browser."""

__version__ = "0.1.0"

GRAVITY = 9.81  # m/s², the g of Δz_vrp = g b²
