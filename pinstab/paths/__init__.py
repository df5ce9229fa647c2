"""The dynamics paths beside pinstab's own KKT backends (the run info's ``path``): ``core``, the standard rows and
compiled force elements of any scene in one compiled evaluation (:mod:`.core`); and three special paths, kept where a
measurement shows they pay (``python benchmarks/core_vs_special.py``: the same equations, the same compiled RK4 loop,
side by side): ``native``, Pinocchio's ``constraintDynamics`` with its Baumgarte corrector (:mod:`.native`: the
four-bar costs 1.21x as much on the core); ``banded``, the same equations of a long chain of point closures solved by a
banded LU at linear cost (:mod:`.banded`: the N-four-bar costs 3.5x, 13x and 38x as much on the core's dense solve at
N = 10, 40 and 80); ``servo``, prescribed joint relations realized by controls (:mod:`.servo`: rows the core does not
take). Their compiled kernels are loaded by :mod:`pinstab.kernels` (``pinstab._compiled``, sources in ``cpp/``)."""
