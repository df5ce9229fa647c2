"""Stability of the time step: the discrete criterion of the constraint deviations and the largest stable step of a
scheme (:mod:`.criterion`), the stability functions of Runge-Kutta tableaus, explicit and implicit, and the growth per
step they give a linear motion (:mod:`.regions`), and the stiffest mode of a scene's linearized motion with the force
element that owns it (:mod:`.modes`). Maps of runs over a grid, observed beside predicted, are an analysis of runs:
:mod:`pinstab.analysis.stability_map`, :mod:`pinstab.analysis.element_map`."""
