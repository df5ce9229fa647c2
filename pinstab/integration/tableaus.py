"""Explicit Runge-Kutta tableaus with embedded error estimators: Dormand-Prince 5(4) (``dopri5``, 7
stages, the last at the new point) and Dormand-Prince 8(5,3) (``dop853``, 12 stages).

Coefficients as published by J. R. Dormand and P. J. Prince, *A family of embedded Runge-Kutta formulae*
(J. Comp. Appl. Math. 6, 1980) and by E. Hairer, S. P. Norsett and G. Wanner, *Solving Ordinary
Differential Equations I* (2nd ed., Springer 1993), section II.10, in the digits SciPy's ``rk.py`` and
``dop853_coefficients`` carry (BSD-3-Clause).

An error estimator is a weight per stage (index ``stages``: the derivative at the new point, which
Dormand-Prince 5(4) uses and DOP853 does not): the estimate is ``h sum_i e_i k_i``.
"""

from __future__ import annotations

from typing import NamedTuple


class Tableau(NamedTuple):
    """An explicit Runge-Kutta tableau with its error estimators.

    Attributes:
        nodes: c_i. coupling: the non-zero a_ij, row by row. weights: the non-zero b_j of the solution kept.
        order: the order of that solution. estimators: one or two error estimators (DOP853: the 5th- and
            3rd-order ones, combined as Hairer's DOP853 code does). estimator_order: the order the step-size
            control assumes for the error (the exponent is -1 / (estimator_order + 1)).
    """

    nodes: tuple[float, ...]
    coupling: dict[int, dict[int, float]]
    weights: dict[int, float]
    order: int
    estimators: tuple[dict[int, float], ...]
    estimator_order: int


NODES = (
    0.0,
    0.526001519587677318785587544488e-01,
    0.789002279381515978178381316732e-01,
    0.118350341907227396726757197510,
    0.281649658092772603273242802490,
    0.333333333333333333333333333333,
    0.25,
    0.307692307692307692307692307692,
    0.651282051282051282051282051282,
    0.6,
    0.857142857142857142857142857142,
    1.0,
)
"""c_i: stage times as fractions of the step."""

COUPLING: dict[int, dict[int, float]] = {
    1: {0: 5.26001519587677318785587544488e-2},
    2: {0: 1.97250569845378994544595329183e-2, 1: 5.91751709536136983633785987549e-2},
    3: {0: 2.95875854768068491816892993775e-2, 2: 8.87627564304205475450678981324e-2},
    4: {
        0: 2.41365134159266685502369798665e-1,
        2: -8.84549479328286085344864962717e-1,
        3: 9.24834003261792003115737966543e-1,
    },
    5: {
        0: 3.7037037037037037037037037037e-2,
        3: 1.70828608729473871279604482173e-1,
        4: 1.25467687566822425016691814123e-1,
    },
    6: {
        0: 3.7109375e-2,
        3: 1.70252211019544039314978060272e-1,
        4: 6.02165389804559606850219397283e-2,
        5: -1.7578125e-2,
    },
    7: {
        0: 3.70920001185047927108779319836e-2,
        3: 1.70383925712239993810214054705e-1,
        4: 1.07262030446373284651809199168e-1,
        5: -1.53194377486244017527936158236e-2,
        6: 8.27378916381402288758473766002e-3,
    },
    8: {
        0: 6.24110958716075717114429577812e-1,
        3: -3.36089262944694129406857109825,
        4: -8.68219346841726006818189891453e-1,
        5: 2.75920996994467083049415600797e1,
        6: 2.01540675504778934086186788979e1,
        7: -4.34898841810699588477366255144e1,
    },
    9: {
        0: 4.77662536438264365890433908527e-1,
        3: -2.48811461997166764192642586468,
        4: -5.90290826836842996371446475743e-1,
        5: 2.12300514481811942347288949897e1,
        6: 1.52792336328824235832596922938e1,
        7: -3.32882109689848629194453265587e1,
        8: -2.03312017085086261358222928593e-2,
    },
    10: {
        0: -9.3714243008598732571704021658e-1,
        3: 5.18637242884406370830023853209,
        4: 1.09143734899672957818500254654,
        5: -8.14978701074692612513997267357,
        6: -1.85200656599969598641566180701e1,
        7: 2.27394870993505042818970056734e1,
        8: 2.49360555267965238987089396762,
        9: -3.0467644718982195003823669022,
    },
    11: {
        0: 2.27331014751653820792359768449,
        3: -1.05344954667372501984066689879e1,
        4: -2.00087205822486249909675718444,
        5: -1.79589318631187989172765950534e1,
        6: 2.79488845294199600508499808837e1,
        7: -2.85899827713502369474065508674,
        8: -8.87285693353062954433549289258,
        9: 1.23605671757943030647266201528e1,
        10: 6.43392746015763530355970484046e-1,
    },
}
"""a_ij: the non-zero entries of the lower triangle, row by row."""

WEIGHTS: dict[int, float] = {
    0: 5.42937341165687622380535766363e-2,
    5: 4.45031289275240888144113950566,
    6: 1.89151789931450038304281599044,
    7: -5.8012039600105847814672114227,
    8: 3.1116436695781989440891606237e-1,
    9: -1.52160949662516078556178806805e-1,
    10: 2.01365400804030348374776537501e-1,
    11: 4.47106157277725905176885569043e-2,
}
"""b_j: the non-zero weights of the order-8 solution."""

ESTIMATOR_5: dict[int, float] = {
    0: 0.1312004499419488073250102996e-1,
    5: -0.1225156446376204440720569753e1,
    6: -0.4957589496572501915214079952,
    7: 0.1664377182454986536961530415e1,
    8: -0.3503288487499736816886487290,
    9: 0.3341791187130174790297318841,
    10: 0.8192320648511571246570742613e-1,
    11: -0.2235530786388629525884427845e-1,
}
"""The 5th-order error estimator of DOP853."""

ESTIMATOR_3: dict[int, float] = {
    j: WEIGHTS.get(j, 0.0)
    - {0: 0.244094488188976377952755905512, 8: 0.733846688281611857341361741547}.get(j, 0.0)
    - {11: 0.220588235294117647058823529412e-1}.get(j, 0.0)
    for j in range(12)
}
"""The 3rd-order error estimator of DOP853 (the weights less a 3rd-order solution's)."""

DOP853 = Tableau(NODES, COUPLING, WEIGHTS, 8, (ESTIMATOR_5, ESTIMATOR_3), 7)

DOPRI5 = Tableau(
    nodes=(0.0, 1 / 5, 3 / 10, 4 / 5, 8 / 9, 1.0),
    coupling={
        1: {0: 1 / 5},
        2: {0: 3 / 40, 1: 9 / 40},
        3: {0: 44 / 45, 1: -56 / 15, 2: 32 / 9},
        4: {0: 19372 / 6561, 1: -25360 / 2187, 2: 64448 / 6561, 3: -212 / 729},
        5: {0: 9017 / 3168, 1: -355 / 33, 2: 46732 / 5247, 3: 49 / 176, 4: -5103 / 18656},
    },
    weights={0: 35 / 384, 2: 500 / 1113, 3: 125 / 192, 4: -2187 / 6784, 5: 11 / 84},
    order=5,
    estimators=({0: -71 / 57600, 2: 71 / 16695, 3: -71 / 1920, 4: 17253 / 339200, 5: -22 / 525, 6: 1 / 40},),
    estimator_order=4,
)
"""Dormand-Prince 5(4): 6 stages; its error estimator also uses the derivative at the new point (index 6),
which is the next step's first stage (first same as last)."""
