"""Periodic orbits of smooth and impacting systems, their stability, and continuation."""

from .continuation import Bifurcation as Bifurcation
from .continuation import OrbitBranch as OrbitBranch
from .continuation import continue_orbits as continue_orbits
from .orbit import PeriodicOrbit as PeriodicOrbit
from .orbit import periodic_orbit as periodic_orbit
from .stability_map import orbit_map as orbit_map
