"""Butcher tableaus of the explicit Runge-Kutta methods and the Radau IIA collocation constants.

Every table is a published one; the tests (tests/integrators/test_tableaus.py) check each against the
Runge-Kutta order conditions, so a mistyped digit shows up as a failed order condition.

Sources
- Euler, Heun (explicit trapezoidal rule), classical RK4: Hairer, Norsett, Wanner, "Solving Ordinary
  Differential Equations I" (HNW I), 2nd ed., 1993, Sec. II.1, Table 1.1-1.2.
- Bogacki-Shampine 3(2): P. Bogacki, L. F. Shampine, Appl. Math. Lett. 2(4), 1989, pp. 321-325.
- Dormand-Prince 5(4) and its 4th-order continuous extension: J. R. Dormand, P. J. Prince, J. Comput.
  Appl. Math. 6(1), 1980; L. F. Shampine, Math. Comp. 46(173), 1986, p. 135 (dense output weights).
- DOP853, 8th-order propagating formula with 5th- and 3rd-order error estimators and the 7th-order dense
  output (three extra stages): HNW I Sec. II.10, and the authors' public Fortran code dop853.f
  (coefficients to 30 digits, reproduced below as decimal literals).
- Radau IIA order 5 (3-stage collocation at the Radau points): E. Hairer, G. Wanner, "Solving Ordinary
  Differential Equations II" (HW II), 2nd ed., 1996, Sec. IV.5, Table 5.6 and Sec. IV.8 (error estimate).
"""
import numpy as np


class ButcherTableau:
    """An explicit Runge-Kutta table ``(A, b, c)`` plus optional embedded-error and dense-output weights.

    ``A`` is strictly lower triangular, shape (s, s); ``b`` the propagating weights (s,); ``c`` the nodes.
    ``error_weights`` (s + 1,) give ``b - b_hat`` including the FSAL stage ``f(t + h, y_new)`` as the
    last entry; ``dense_weights`` (s + 1, p) give the continuous extension
    ``y(t + theta h) = y + h * sum_i k_i * sum_k P[i, k] theta**(k + 1)``.
    """

    def __init__(self, name, order, A, b, c, error_weights=None, error_order=None, dense_weights=None):
        self.name = name
        self.order = order
        self.A = np.ascontiguousarray(A, dtype=np.float64)
        self.b = np.ascontiguousarray(b, dtype=np.float64)
        self.c = np.ascontiguousarray(c, dtype=np.float64)
        self.n_stages = self.b.shape[0]
        self.error_weights = None if error_weights is None else np.ascontiguousarray(error_weights, dtype=np.float64)
        self.error_order = error_order
        self.dense_weights = None if dense_weights is None else np.ascontiguousarray(dense_weights, dtype=np.float64)

    def stability_function(self, z):
        """Linear stability function R(z) = 1 + z b^T (I - z A)^-1 1 for complex z (scalar or array).

        A is strictly lower triangular (nilpotent), so R is the polynomial 1 + sum_k (b^T A^(k-1) 1) z^k.
        """
        coefficients = [1.0]
        v = np.ones(self.n_stages)
        for _ in range(self.n_stages):
            coefficients.append(self.b @ v)
            v = self.A @ v
        z = np.atleast_1d(np.asarray(z, dtype=np.complex128))
        return np.polyval(coefficients[::-1], z)


EULER = ButcherTableau("euler", 1, [[0.0]], [1.0], [0.0])

HEUN = ButcherTableau("heun", 2, [[0.0, 0.0], [1.0, 0.0]], [0.5, 0.5], [0.0, 1.0])

RK4 = ButcherTableau(
    "rk4", 4,
    [[0.0, 0.0, 0.0, 0.0], [0.5, 0.0, 0.0, 0.0], [0.0, 0.5, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0]],
    [1 / 6, 1 / 3, 1 / 3, 1 / 6], [0.0, 0.5, 0.5, 1.0])

BS32 = ButcherTableau(
    "bs32", 3,
    [[0.0, 0.0, 0.0], [1 / 2, 0.0, 0.0], [0.0, 3 / 4, 0.0]],
    [2 / 9, 1 / 3, 4 / 9], [0.0, 1 / 2, 3 / 4],
    error_weights=[5 / 72, -1 / 12, -1 / 9, 1 / 8], error_order=2,
    # cubic Hermite interpolation through (y, f) at both ends, written in the stage basis
    dense_weights=[[1, -4 / 3, 5 / 9], [0, 1, -2 / 3], [0, 4 / 3, -8 / 9], [0, -1, 1]])

DOPRI5 = ButcherTableau(
    "dopri5", 5,
    [[0, 0, 0, 0, 0, 0],
     [1 / 5, 0, 0, 0, 0, 0],
     [3 / 40, 9 / 40, 0, 0, 0, 0],
     [44 / 45, -56 / 15, 32 / 9, 0, 0, 0],
     [19372 / 6561, -25360 / 2187, 64448 / 6561, -212 / 729, 0, 0],
     [9017 / 3168, -355 / 33, 46732 / 5247, 49 / 176, -5103 / 18656, 0]],
    [35 / 384, 0, 500 / 1113, 125 / 192, -2187 / 6784, 11 / 84],
    [0, 1 / 5, 3 / 10, 4 / 5, 8 / 9, 1],
    error_weights=[-71 / 57600, 0, 71 / 16695, -71 / 1920, 17253 / 339200, -22 / 525, 1 / 40], error_order=4,
    dense_weights=[
        [1, -8048581381 / 2820520608, 8663915743 / 2820520608, -12715105075 / 11282082432],
        [0, 0, 0, 0],
        [0, 131558114200 / 32700410799, -68118460800 / 10900136933, 87487479700 / 32700410799],
        [0, -1754552775 / 470086768, 14199869525 / 1410260304, -10690763975 / 1880347072],
        [0, 127303824393 / 49829197408, -318862633887 / 49829197408, 701980252875 / 199316789632],
        [0, -282668133 / 205662961, 2019193451 / 616988883, -1453857185 / 822651844],
        [0, 40617522 / 29380423, -110615467 / 29380423, 69997945 / 29380423]])

# --- DOP853 (Hairer & Wanner, dop853.f). Stage 12 (0-based) is the FSAL stage f(t + h, y_new);
# stages 13-15 are only needed for the 7th-order dense output.
_DOP853_NODES = (
    0.0, 0.526001519587677318785587544488e-01, 0.789002279381515978178381316732e-01,
    0.118350341907227396726757197510, 0.281649658092772603273242802490, 0.333333333333333333333333333333,
    0.25, 0.307692307692307692307692307692, 0.651282051282051282051282051282,
    0.6, 0.857142857142857142857142857142, 1.0,
    1.0, 0.1, 0.2,
    0.777777777777777777777777777778,
)
_DOP853_COUPLING = {  # row: ((column, a_ij), ...)
    1: (
        (0, 5.26001519587677318785587544488e-2),
    ),
    2: (
        (0, 1.97250569845378994544595329183e-2), (1, 5.91751709536136983633785987549e-2),
    ),
    3: (
        (0, 2.95875854768068491816892993775e-2), (2, 8.87627564304205475450678981324e-2),
    ),
    4: (
        (0, 2.41365134159266685502369798665e-1), (2, -8.84549479328286085344864962717e-1),
        (3, 9.24834003261792003115737966543e-1),
    ),
    5: (
        (0, 3.7037037037037037037037037037e-2), (3, 1.70828608729473871279604482173e-1),
        (4, 1.25467687566822425016691814123e-1),
    ),
    6: (
        (0, 3.7109375e-2), (3, 1.70252211019544039314978060272e-1),
        (4, 6.02165389804559606850219397283e-2), (5, -1.7578125e-2),
    ),
    7: (
        (0, 3.70920001185047927108779319836e-2), (3, 1.70383925712239993810214054705e-1),
        (4, 1.07262030446373284651809199168e-1), (5, -1.53194377486244017527936158236e-2),
        (6, 8.27378916381402288758473766002e-3),
    ),
    8: (
        (0, 6.24110958716075717114429577812e-1), (3, -3.36089262944694129406857109825),
        (4, -8.68219346841726006818189891453e-1), (5, 2.75920996994467083049415600797e1),
        (6, 2.01540675504778934086186788979e1), (7, -4.34898841810699588477366255144e1),
    ),
    9: (
        (0, 4.77662536438264365890433908527e-1), (3, -2.48811461997166764192642586468),
        (4, -5.90290826836842996371446475743e-1), (5, 2.12300514481811942347288949897e1),
        (6, 1.52792336328824235832596922938e1), (7, -3.32882109689848629194453265587e1),
        (8, -2.03312017085086261358222928593e-2),
    ),
    10: (
        (0, -9.3714243008598732571704021658e-1), (3, 5.18637242884406370830023853209),
        (4, 1.09143734899672957818500254654), (5, -8.14978701074692612513997267357),
        (6, -1.85200656599969598641566180701e1), (7, 2.27394870993505042818970056734e1),
        (8, 2.49360555267965238987089396762), (9, -3.0467644718982195003823669022),
    ),
    11: (
        (0, 2.27331014751653820792359768449), (3, -1.05344954667372501984066689879e1),
        (4, -2.00087205822486249909675718444), (5, -1.79589318631187989172765950534e1),
        (6, 2.79488845294199600508499808837e1), (7, -2.85899827713502369474065508674),
        (8, -8.87285693353062954433549289258), (9, 1.23605671757943030647266201528e1),
        (10, 6.43392746015763530355970484046e-1),
    ),
    12: (
        (0, 5.42937341165687622380535766363e-2), (5, 4.45031289275240888144113950566),
        (6, 1.89151789931450038304281599044), (7, -5.8012039600105847814672114227),
        (8, 3.1116436695781989440891606237e-1), (9, -1.52160949662516078556178806805e-1),
        (10, 2.01365400804030348374776537501e-1), (11, 4.47106157277725905176885569043e-2),
    ),
    13: (
        (0, 5.61675022830479523392909219681e-2), (6, 2.53500210216624811088794765333e-1),
        (7, -2.46239037470802489917441475441e-1), (8, -1.24191423263816360469010140626e-1),
        (9, 1.5329179827876569731206322685e-1), (10, 8.20105229563468988491666602057e-3),
        (11, 7.56789766054569976138603589584e-3), (12, -8.298e-3),
    ),
    14: (
        (0, 3.18346481635021405060768473261e-2), (5, 2.83009096723667755288322961402e-2),
        (6, 5.35419883074385676223797384372e-2), (7, -5.49237485713909884646569340306e-2),
        (10, -1.08347328697249322858509316994e-4), (11, 3.82571090835658412954920192323e-4),
        (12, -3.40465008687404560802977114492e-4), (13, 1.41312443674632500278074618366e-1),
    ),
    15: (
        (0, -4.28896301583791923408573538692e-1), (5, -4.69762141536116384314449447206),
        (6, 7.68342119606259904184240953878), (7, 4.06898981839711007970213554331),
        (8, 3.56727187455281109270669543021e-1), (12, -1.39902416515901462129418009734e-3),
        (13, 2.9475147891527723389556272149), (14, -9.15095847217987001081870187138),
    ),
}
_DOP853_DENSE = {
    0: (
        (0, -0.84289382761090128651353491142e+1), (5, 0.56671495351937776962531783590),
        (6, -0.30689499459498916912797304727e+1), (7, 0.23846676565120698287728149680e+1),
        (8, 0.21170345824450282767155149946e+1), (9, -0.87139158377797299206789907490),
        (10, 0.22404374302607882758541771650e+1), (11, 0.63157877876946881815570249290),
        (12, -0.88990336451333310820698117400e-1), (13, 0.18148505520854727256656404962e+2),
        (14, -0.91946323924783554000451984436e+1), (15, -0.44360363875948939664310572000e+1),
    ),
    1: (
        (0, 0.10427508642579134603413151009e+2), (5, 0.24228349177525818288430175319e+3),
        (6, 0.16520045171727028198505394887e+3), (7, -0.37454675472269020279518312152e+3),
        (8, -0.22113666853125306036270938578e+2), (9, 0.77334326684722638389603898808e+1),
        (10, -0.30674084731089398182061213626e+2), (11, -0.93321305264302278729567221706e+1),
        (12, 0.15697238121770843886131091075e+2), (13, -0.31139403219565177677282850411e+2),
        (14, -0.93529243588444783865713862664e+1), (15, 0.35816841486394083752465898540e+2),
    ),
    2: (
        (0, 0.19985053242002433820987653617e+2), (5, -0.38703730874935176555105901742e+3),
        (6, -0.18917813819516756882830838328e+3), (7, 0.52780815920542364900561016686e+3),
        (8, -0.11573902539959630126141871134e+2), (9, 0.68812326946963000169666922661e+1),
        (10, -0.10006050966910838403183860980e+1), (11, 0.77771377980534432092869265740),
        (12, -0.27782057523535084065932004339e+1), (13, -0.60196695231264120758267380846e+2),
        (14, 0.84320405506677161018159903784e+2), (15, 0.11992291136182789328035130030e+2),
    ),
    3: (
        (0, -0.25693933462703749003312586129e+2), (5, -0.15418974869023643374053993627e+3),
        (6, -0.23152937917604549567536039109e+3), (7, 0.35763911791061412378285349910e+3),
        (8, 0.93405324183624310003907691704e+2), (9, -0.37458323136451633156875139351e+2),
        (10, 0.10409964950896230045147246184e+3), (11, 0.29840293426660503123344363579e+2),
        (12, -0.43533456590011143754432175058e+2), (13, 0.96324553959188282948394950600e+2),
        (14, -0.39177261675615439165231486172e+2), (15, -0.14972683625798562581422125276e+3),
    ),
}

_DOP853_ERR3_B_HAT = ((0, 0.244094488188976377952755905512), (8, 0.733846688281611857341361741547),
                      (11, 0.220588235294117647058823529412e-1))
_DOP853_ERR5 = ((0, 0.1312004499419488073250102996e-1), (5, -0.1225156446376204440720569753e+1),
                (6, -0.4957589496572501915214079952), (7, 0.1664377182454986536961530415e+1),
                (8, -0.3503288487499736816886487290), (9, 0.3341791187130174790297318841),
                (10, 0.8192320648511571246570742613e-1), (11, -0.2235530786388629525884427845e-1))


def _dop853_tables():
    n_ext = len(_DOP853_NODES)
    A = np.zeros((n_ext, n_ext))
    for row, entries in _DOP853_COUPLING.items():
        for col, value in entries:
            A[row, col] = value
    c = np.array(_DOP853_NODES)
    b = A[12, :12].copy()
    err5 = np.zeros(13)
    for col, value in _DOP853_ERR5:
        err5[col] = value
    err3 = np.zeros(13)
    err3[:12] = b
    for col, value in _DOP853_ERR3_B_HAT:
        err3[col] -= value
    D = np.zeros((4, n_ext))
    for row, entries in _DOP853_DENSE.items():
        for col, value in entries:
            D[row, col] = value
    return A, b, c, err5, err3, D


DOP853_A_EXTENDED, _b853, DOP853_C_EXTENDED, DOP853_ERR5, DOP853_ERR3, DOP853_DENSE = _dop853_tables()
DOP853 = ButcherTableau("dop853", 8, DOP853_A_EXTENDED[:12, :12], _b853, DOP853_C_EXTENDED[:12],
                        error_weights=DOP853_ERR5, error_order=7)
# The same 12-stage 8th-order formula used with a fixed step ("rk8").
RK8 = ButcherTableau("rk8", 8, DOP853_A_EXTENDED[:12, :12], _b853, DOP853_C_EXTENDED[:12])


def _radau_iia5_constants():
    """Radau IIA (s = 3, order 5) coefficients and the real/complex eigen-decomposition of A^-1.

    HW II Sec. IV.8: with W = T^-1 Z the Newton system decouples into one real (gamma) and one
    complex (alpha + i beta) linear system of the size of the ODE.
    """
    s6 = np.sqrt(6.0)
    c = np.array([(4 - s6) / 10, (4 + s6) / 10, 1.0])
    A = np.array([
        [(88 - 7 * s6) / 360, (296 - 169 * s6) / 1800, (-2 + 3 * s6) / 225],
        [(296 + 169 * s6) / 1800, (88 + 7 * s6) / 360, (-2 - 3 * s6) / 225],
        [(16 - s6) / 36, (16 + s6) / 36, 1 / 9]])
    # error estimator weights e (HW II eq. IV.8.19 with gamma0 = 1/gamma): err = (gamma0 h) f0 + Z e
    e = np.array([-13 - 7 * s6, -13 + 7 * s6, -1.0]) / 3
    eigvals, vecs = np.linalg.eig(np.linalg.inv(A))
    real_index = int(np.argmin(np.abs(eigvals.imag)))
    complex_index = [i for i in range(3) if i != real_index and eigvals[i].imag > 0][0]
    gamma = eigvals[real_index].real
    alpha = eigvals[complex_index].real
    beta = eigvals[complex_index].imag
    v_real = vecs[:, real_index].real
    v_complex = vecs[:, complex_index]
    # A^-1 (x + i y) = (alpha + i beta)(x + i y)  =>  A^-1 [x, y] = [x, y] [[alpha, beta], [-beta, alpha]]
    T = np.column_stack([v_real, v_complex.real, v_complex.imag])
    T_inv = np.linalg.inv(T)
    return c, A, e, gamma, alpha, beta, T, T_inv


(RADAU_C, RADAU_A, RADAU_ERROR_WEIGHTS, RADAU_GAMMA, RADAU_ALPHA, RADAU_BETA,
 RADAU_T, RADAU_T_INV) = _radau_iia5_constants()
