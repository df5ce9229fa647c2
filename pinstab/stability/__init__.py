"""Stability of the time step: the discrete criterion of the constraint deviations and the largest stable step of a
scheme (:mod:`.criterion`), and the stiffest mode of a scene's linearized motion with the force element that owns it
(:mod:`.modes`). Maps of runs over a grid, observed beside predicted, are an analysis of runs:
:mod:`pinstab.analysis.stability_map`."""
