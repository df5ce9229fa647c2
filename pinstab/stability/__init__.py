"""Stability of the time step: the discrete criterion of the constraint deviations, the growth per step a scheme gives
a linear motion's modes and the stability limit of a stiff mode (:mod:`.criterion`), the stability functions of
Runge-Kutta tableaus, explicit and implicit, in the one registry of the schemes' tableaus (:mod:`.regions`), and the
stiffest mode of a scene's linearized motion with the force element that owns it (:mod:`.modes`). Maps of runs over a
grid, observed beside predicted, are an analysis of runs: :mod:`pinstab.analysis.stability_map`,
:mod:`pinstab.analysis.element_map`."""
