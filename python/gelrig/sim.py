"""The simulated bench from Python: frames of a GelSight for a contact given by hand, with
every marker's exact centre and the contact's force at equilibrium.

    >>> bench = gelrig.sim.Bench("box", indenter={"shape": "sphere", "diameter": "12.68 mm"})
    >>> frame, wrench, truth = bench.press(0.5)
    >>> frame, wrench, truth = bench.press(0.5, shear_mm=0.2)   # truth["stick_fraction"]
"""

from ._gelrig import Bench

__all__ = ["Bench"]
