"""Reference problems with closed-form solutions, for verifying integrators and choosing among them.

- :func:`linear_oscillator`: x'' + 2 zeta omega x' + omega^2 x = 0.
- :class:`TorqueFreeRigidBody`: Euler's equations ``I w' = -w x (I w)`` of an asymmetric body in its
  principal frame, solved with Jacobi elliptic functions (Landau & Lifshitz, Mechanics, 3rd ed., Sec. 37,
  eqs. 37.10-37.12; the case H^2 < 2 T I_2 follows by exchanging axes 1 and 3). The signs and the phase
  are fitted to an arbitrary initial angular velocity (derivation in the class docstring).
- :class:`FreeFreeBeamModes`: modal model of a uniform free-free Euler-Bernoulli beam, frequencies
  ``omega_n = (beta_n L)^2 sqrt(E I / (rho A L^4))`` with ``cos(beta L) cosh(beta L) = 1`` (Blevins,
  "Formulas for Natural Frequency and Mode Shape", 1979, Table 8-1), two rigid-body modes and light modal
  damping; each modal coordinate has the closed-form damped free response.
- :class:`TipForcedBeam`: the same beam at rest, driven at its tip by a slow sinusoidal force (closed-form
  forced response); high modes follow quasi-statically (stiff).
- :func:`spinning_spacecraft_pd`: attitude (quaternion + body rates) of a rigid spacecraft under a PD
  controller with a reaction-wheel-like torque limit; no closed form (the reference is DOP853 at
  rtol = 1e-13), used as the closed-loop scene of the work-precision study.
"""
import numpy as np
from scipy.optimize import brentq
from scipy.special import ellipj, ellipkinc


def linear_oscillator(omega, zeta=0.0):
    """Return ``(fun, exact)`` for y = [x, v], x(0) = 1, v(0) = 0 (0 <= zeta < 1)."""
    if not 0.0 <= zeta < 1.0:
        raise ValueError(f"zeta must lie in [0, 1), got {zeta}")
    wd = omega * np.sqrt(1 - zeta * zeta)
    a = zeta * omega

    def fun(t, y):
        return np.array([y[1], -omega * omega * y[0] - 2 * zeta * omega * y[1]])

    def exact(t):
        e = np.exp(-a * t)
        c = np.cos(wd * t)
        s = np.sin(wd * t)
        x = e * (c + a / wd * s)
        v = -e * (omega * omega / wd) * s
        return np.array([x, v])

    return fun, exact


class TorqueFreeRigidBody:
    """Torque-free asymmetric rigid body: body-frame angular velocity in closed form.

    Principal moments must be distinct and are sorted internally (I1 < I2 < I3). With 2T = sum I_i w_i^2,
    H^2 = sum I_i^2 w_i^2 and D = H^2 / (2T):

    D > I2 (rotation about the major axis 3 family):
        w1 = A1 cn(tau), w2 = s A2 sn(tau), w3 = s A3 dn(tau), s = sign(w3(0)),
        A1^2 = (2T I3 - H^2) / (I1 (I3 - I1)), A2^2 = (2T I3 - H^2) / (I2 (I3 - I2)),
        A3^2 = (H^2 - 2T I1) / (I3 (I3 - I1)),
        tau = lambda t + tau0, lambda^2 = (I3 - I2)(H^2 - 2T I1) / (I1 I2 I3),
        m = k^2 = (I2 - I1)(2T I3 - H^2) / ((I3 - I2)(H^2 - 2T I1)).
    D < I2 (minor axis 1 family), axes 1 and 3 exchanged:
        w1 = s A1 dn(tau), w2 = s A2 sn(tau), w3 = A3 cn(tau), s = sign(w1(0)),
        A1^2 = (H^2 - 2T I3) / (I1 (I1 - I3)), A2^2 = (H^2 - 2T I1) / (I2 (I2 - I1)),
        A3^2 = (2T I1 - H^2) / (I3 (I1 - I3)),
        lambda^2 = (I2 - I1)(2T I3 - H^2) / (I1 I2 I3), m = (I3 - I2)(H^2 - 2T I1) / ((I2 - I1)(2T I3 - H^2)).
    The sign pattern is the one for which the Euler equations hold term by term (d cn = -sn dn,
    d sn = cn dn, d dn = -m sn cn, times lambda). The phase tau0 = F(phi0 | m) (incomplete elliptic integral
    of the first kind) with phi0 = atan2(sn(tau0), cn(tau0)) read from the initial condition.
    The separatrix D = I2 (a homoclinic orbit) is refused. Sorting the axes by an odd permutation reverses
    the sign of Euler's equations, so such a body is evaluated at -t.
    """

    def __init__(self, inertia, omega0):
        inertia = np.asarray(inertia, dtype=np.float64)
        omega0 = np.asarray(omega0, dtype=np.float64)
        if inertia.shape != (3,) or omega0.shape != (3,):
            raise ValueError("inertia and omega0 must be 3-vectors (principal moments, body rates)")
        order = np.argsort(inertia)
        I1, I2, I3 = inertia[order]
        if not (I1 < I2 < I3):
            raise ValueError(f"principal moments must be distinct for the asymmetric solution, got {inertia}")
        self.inertia = inertia
        self.order = order
        # Euler's equations are invariant under cyclic relabelling of the axes only; an odd permutation
        # reverses the sign of the right-hand side, i.e. the sorted body runs backwards in time
        self.time_sign = float(np.linalg.det(np.eye(3)[order]))
        w = omega0[order]
        two_T = float(np.sum(np.array([I1, I2, I3]) * w * w))
        H2 = float(np.sum((np.array([I1, I2, I3]) * w) ** 2))
        D = H2 / two_T
        if abs(D - I2) < 1e-12 * I2:
            raise ValueError("initial rates lie on the separatrix H^2 = 2 T I2; choose another omega0")
        self.major_family = D > I2
        if self.major_family:
            A1 = np.sqrt((two_T * I3 - H2) / (I1 * (I3 - I1)))
            A2 = np.sqrt((two_T * I3 - H2) / (I2 * (I3 - I2)))
            A3 = np.sqrt((H2 - two_T * I1) / (I3 * (I3 - I1)))
            lam = np.sqrt((I3 - I2) * (H2 - two_T * I1) / (I1 * I2 * I3))
            m = (I2 - I1) * (two_T * I3 - H2) / ((I3 - I2) * (H2 - two_T * I1))
            s = 1.0 if w[2] >= 0 else -1.0
            cn0 = w[0] / A1
            sn0 = w[1] / (s * A2)
        else:
            A1 = np.sqrt((H2 - two_T * I3) / (I1 * (I1 - I3)))
            A2 = np.sqrt((H2 - two_T * I1) / (I2 * (I2 - I1)))
            A3 = np.sqrt((two_T * I1 - H2) / (I3 * (I1 - I3)))
            lam = np.sqrt((I2 - I1) * (two_T * I3 - H2) / (I1 * I2 * I3))
            m = (I3 - I2) * (H2 - two_T * I1) / ((I2 - I1) * (two_T * I3 - H2))
            s = 1.0 if w[0] >= 0 else -1.0
            cn0 = w[2] / A3
            sn0 = w[1] / (s * A2)
        phi0 = np.arctan2(sn0, cn0)
        self.tau0 = ellipkinc(phi0, m)
        self.amplitudes = (A1, A2, A3)
        self.rate = lam
        self.m = m
        self.sign = s
        self.two_T = two_T
        self.H2 = H2

    def omega(self, t):
        """Body-frame angular velocity at time(s) t, shape (3,) or (3, len(t)), in the caller's axis order."""
        t = np.asarray(t, dtype=np.float64)
        sn, cn, dn, _ = ellipj(self.rate * self.time_sign * t + self.tau0, self.m)
        A1, A2, A3 = self.amplitudes
        s = self.sign
        if self.major_family:
            w_sorted = np.array([A1 * cn, s * A2 * sn, s * A3 * dn])
        else:
            w_sorted = np.array([s * A1 * dn, s * A2 * sn, A3 * cn])
        out = np.empty_like(w_sorted)
        out[self.order] = w_sorted
        return out

    def euler_equations(self):
        """``fun(t, w)`` of Euler's torque-free equations in the body principal frame."""
        I = self.inertia.copy()
        c1 = (I[1] - I[2]) / I[0]
        c2 = (I[2] - I[0]) / I[1]
        c3 = (I[0] - I[1]) / I[2]

        def fun(t, w):
            return np.array([c1 * w[1] * w[2], c2 * w[2] * w[0], c3 * w[0] * w[1]])

        return fun


def free_free_beam_roots(n_modes):
    """First n roots beta_n L of cos(x) cosh(x) = 1 (x > 0), elastic modes of a free-free beam."""
    roots = []
    for k in range(1, n_modes + 1):
        guess = (2 * k + 1) * np.pi / 2
        roots.append(brentq(lambda x: np.cos(x) - 1.0 / np.cosh(x), guess - 0.3, guess + 0.3, xtol=1e-15))
    return np.array(roots)


class FreeFreeBeamModes:
    """Modal model of a uniform free-free beam in bending: two rigid-body modes and elastic modes up to
    ``f_max`` Hz, each with damping ratio ``zeta``; state y = [eta (n), eta_dot (n)].

    ``length`` (m), ``EI`` (N m^2), ``rho_A`` (kg/m): defaults give a 10 m aluminium-tube-like appendage
    whose first elastic mode is ~1 Hz. ``eta0``/``eta_dot0`` default to a deterministic broadband initial
    condition exciting every mode (1 mm / (mode number) amplitude, as after a pyro shock).
    """

    def __init__(self, f_max=100.0, zeta=0.005, length=10.0, EI=None, rho_A=2.0, eta0=None, eta_dot0=None):
        if EI is None:
            # first elastic frequency 1 Hz: omega_1 = 4.730^2 sqrt(EI / (rho_A L^4))
            EI = rho_A * length ** 4 * (2 * np.pi / free_free_beam_roots(1)[0] ** 2) ** 2
        scale = np.sqrt(EI / (rho_A * length ** 4))
        n_elastic = 1
        while free_free_beam_roots(n_elastic + 1)[-1] ** 2 * scale / (2 * np.pi) <= f_max:
            n_elastic += 1
        roots = free_free_beam_roots(n_elastic)
        self.elastic_omega = roots ** 2 * scale
        self.omega = np.concatenate([[0.0, 0.0], self.elastic_omega])
        self.zeta = np.where(self.omega > 0, zeta, 0.0)
        self.n_modes = self.omega.size
        n = self.n_modes
        k = np.arange(1, n + 1)
        self.eta0 = 1e-3 / k if eta0 is None else np.asarray(eta0, dtype=np.float64)
        self.eta_dot0 = (1e-3 * np.where(k % 2 == 0, 1.0, -1.0) * np.maximum(self.omega, 1.0) / k ** 2
                         if eta_dot0 is None else np.asarray(eta_dot0, dtype=np.float64))
        self.y0 = np.concatenate([self.eta0, self.eta_dot0])
        self.stiffness = self.omega ** 2
        self.damping = 2 * self.zeta * self.omega

    def fun(self, t, y):
        n = self.n_modes
        out = np.empty(2 * n)
        out[:n] = y[n:]
        out[n:] = -self.stiffness * y[:n] - self.damping * y[n:]
        return out

    def jacobian(self):
        n = self.n_modes
        J = np.zeros((2 * n, 2 * n))
        J[:n, n:] = np.eye(n)
        J[n:, :n] = -np.diag(self.stiffness)
        J[n:, n:] = -np.diag(self.damping)
        return J

    def exact(self, t):
        """Closed-form state at time t (scalar)."""
        eta = np.empty(self.n_modes)
        eta_dot = np.empty(self.n_modes)
        for i in range(self.n_modes):
            w, z, x0, v0 = self.omega[i], self.zeta[i], self.eta0[i], self.eta_dot0[i]
            if w == 0.0:
                eta[i] = x0 + v0 * t
                eta_dot[i] = v0
                continue
            a = z * w
            wd = w * np.sqrt(1 - z * z)
            e = np.exp(-a * t)
            c = np.cos(wd * t)
            s = np.sin(wd * t)
            B = (v0 + a * x0) / wd
            eta[i] = e * (x0 * c + B * s)
            eta_dot[i] = e * ((-a * x0 + wd * B) * c + (-a * B - wd * x0) * s)
        return np.concatenate([eta, eta_dot])


class TipForcedBeam:
    """The free-free beam's modes, at rest at t = 0, driven at the tip by F(t) = F0 sin(Omega t) (N);
    state y = [eta, eta_dot]; closed-form response. A slow force makes the high modes follow
    quasi-statically: the classic stiff structural problem.

    Mass-normalized free-free mode shapes have tip values +-2/sqrt(m) for the elastic modes, 1/sqrt(m)
    for translation and sqrt(3/m) for rotation (Blevins Table 8-1 shapes normalized to the beam mass m).
    """

    def __init__(self, f_max, zeta=0.005, force=10.0, frequency_hz=0.05):
        self.beam = FreeFreeBeamModes(f_max=f_max, zeta=zeta)
        beam = self.beam
        n = beam.n_modes
        mass = 2.0 * 10.0  # rho_A * length of the default beam
        tip = np.empty(n)
        tip[0] = 1.0 / np.sqrt(mass)
        tip[1] = np.sqrt(3.0 / mass)
        tip[2:] = 2.0 / np.sqrt(mass) * np.where(np.arange(n - 2) % 2 == 0, 1.0, -1.0)
        self.b = tip * force
        self.Omega = 2 * np.pi * frequency_hz
        self.y0 = np.zeros(2 * n)
        self.n = n

    def fun(self, t, y):
        out = self.beam.fun(t, y)
        out[self.n:] += self.b * np.sin(self.Omega * t)
        return out

    def exact(self, t):
        beam, W, n = self.beam, self.Omega, self.n
        eta = np.empty(n)
        eta_dot = np.empty(n)
        for i in range(n):
            w, z, b = beam.omega[i], beam.zeta[i], self.b[i]
            if w == 0.0:
                eta[i] = b * (t / W - np.sin(W * t) / W ** 2)
                eta_dot[i] = b * (1 - np.cos(W * t)) / W
                continue
            P = b / (w * w - W * W + 2j * z * w * W)  # particular response Im(P e^{i W t})
            xp, vp = (P * np.exp(1j * W * t)).imag, (1j * W * P * np.exp(1j * W * t)).imag
            x0, v0 = -P.imag, -(1j * W * P).imag  # homogeneous part cancels the particular initial state
            a = z * w
            wd = w * np.sqrt(1 - z * z)
            e = np.exp(-a * t)
            B = (v0 + a * x0) / wd
            eta[i] = xp + e * (x0 * np.cos(wd * t) + B * np.sin(wd * t))
            eta_dot[i] = vp + e * ((-a * x0 + wd * B) * np.cos(wd * t) + (-a * B - wd * x0) * np.sin(wd * t))
        return np.concatenate([eta, eta_dot])



def _quat_multiply(p, q):
    return np.array([p[0] * q[0] - p[1] * q[1] - p[2] * q[2] - p[3] * q[3],
                     p[0] * q[1] + p[1] * q[0] + p[2] * q[3] - p[3] * q[2],
                     p[0] * q[2] - p[1] * q[3] + p[2] * q[0] + p[3] * q[1],
                     p[0] * q[3] + p[1] * q[2] - p[2] * q[1] + p[3] * q[0]])


def spinning_spacecraft_pd(inertia=(120.0, 100.0, 80.0), kp=8.0, kd=60.0, torque_limit=0.5,
                           q_target=(np.cos(0.5), np.sin(0.5) / np.sqrt(3), np.sin(0.5) / np.sqrt(3),
                                     np.sin(0.5) / np.sqrt(3))):
    """Closed-loop rigid spacecraft: y = [q (scalar-first, body->inertial), w (body, rad/s)].

    Control torque ``u = sat(-kp * sign(dq_w) * dq_vec - kd * w, torque_limit)`` with ``dq = q_target^* q``
    (quaternion error) and a smooth saturation ``torque_limit * tanh(u / torque_limit)`` so the right-hand
    side stays smooth (the work-precision comparison measures integration error, not a kink).
    Returns ``(fun, y0, normalize, quaternion_w_indices)``.
    """
    I = np.asarray(inertia, dtype=np.float64)
    qt_conj = np.array(q_target) * np.array([1.0, -1.0, -1.0, -1.0])

    def fun(t, y):
        q = y[:4]
        w = y[4:]
        dq = _quat_multiply(qt_conj, q)
        sgn = 1.0 if dq[0] >= 0 else -1.0
        u = -kp * sgn * dq[1:] - kd * w
        u = torque_limit * np.tanh(u / torque_limit)
        q_dot = 0.5 * _quat_multiply(q, np.array([0.0, w[0], w[1], w[2]]))
        w_dot = (u - np.cross(w, I * w)) / I
        return np.concatenate([q_dot, w_dot])

    def normalize(y):
        y[:4] /= np.linalg.norm(y[:4])

    y0 = np.array([1.0, 0.0, 0.0, 0.0, 0.3, -0.2, 0.5])
    return fun, y0, normalize, np.array([0])
