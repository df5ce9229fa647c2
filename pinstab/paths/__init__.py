"""The dynamics paths beside pinstab's own KKT backends (the run info's ``path``): ``native``, Pinocchio's
``constraintDynamics`` with its Baumgarte corrector (:mod:`.native`); ``banded``, the same equations of a long chain
of point closures solved by a banded LU at linear cost (:mod:`.banded`); ``servo``, prescribed joint relations
realized by controls (:mod:`.servo`); their compiled kernels are loaded by :mod:`pinstab.kernels`
(``pinstab._compiled``, sources in ``cpp/``)."""
