"""Mass depletion: propellant consumption changes a rigid body's mass properties during the run.

At each sample (its own rate) the model reads the propellant used so far (kg, e.g. the sum of the
thrusters' ``propellant_used``), and sets the body's mass properties in the engine
(``MultibodySystem.set_mass_properties``, O(1)) to

    m = m_full - used,    f = used / (m_full - m_empty)  (clipped to [0, 1])
    c = (1 - f) c_full + f c_empty,    J = (1 - f) J_full + f J_empty     (about the COM, body axes)

the two-point form of a tank mass-properties table (linear in the fill fraction). The state ``u`` (the
body's velocities) is kept across each change: the thrust model accounts for the momentum the exhaust
carries away, so a constant thrust gives the rocket equation ``dv = Isp g0 ln(m0 / m1)`` (Tsiolkovsky)
in the limit of a fast sample rate, and exactly the sum ``sum_k F T / m_k`` at rate 1/T.

Config: ``body`` (the engine body to deplete), ``engine`` (the engine model's name, default
``multibody``). Parameters are the full and empty mass properties. The engine's mass properties are
set again from the restored state the moment a run is restored (``Model.restored``), so a restart
continues bit-identically, also between two samples.

The update stays Python (``python_update``): it sets the body's mass properties through the engine's
Python API (``set_mass_properties``), which a compiled kernel cannot call.
"""

from __future__ import annotations

from dataclasses import replace

from numba import njit

from shell.model import Declarations, InputPort, Model, ModelError, OutputPort, Parameter, State
from shell.registry import register_model


PARAMETERS = (
    Parameter("full_mass", "kg", None, (), (0.0, None), "body mass with full tanks"),
    Parameter("empty_mass", "kg", None, (), (0.0, None), "body mass with empty tanks"),
    Parameter("full_com", "m", (0.0, 0.0, 0.0), (3,), None, "center of mass, full, body frame"),
    Parameter("empty_com", "m", (0.0, 0.0, 0.0), (3,), None, "center of mass, empty, body frame"),
    Parameter("full_inertia", "kg*m^2", None, (3, 3), None, "inertia about the COM, full, body axes"),
    Parameter("empty_inertia", "kg*m^2", None, (3, 3), None, "inertia about the COM, empty, body axes"),
)
INPUTS = (InputPort("propellant_used", "kg", (), "propellant consumed since t = 0"),)
OUTPUTS = (OutputPort("mass", "kg", (), "current body mass"),
           OutputPort("propellant_remaining", "kg", (), "propellant left"))
DISCRETE = (State("mass", "kg", (), None, "current body mass"),
            State("propellant_remaining", "kg", (), None, "propellant left"),
            State("propellant_used", "kg", (), 0.0, "propellant used at the last sample "
                  "(kept exactly, so a restore re-applies the same mass properties)"))
DEPLETION = Declarations(parameters=PARAMETERS, inputs=INPUTS, outputs=OUTPUTS, discrete=DISCRETE)
P, U, Y, Z = DEPLETION.P, DEPLETION.U, DEPLETION.Y, DEPLETION.Z


@njit(cache=True)
def _held(t, x, z, u, p, y):
    y[Y.mass] = z[Z.mass]
    y[Y.propellant_remaining] = z[Z.propellant_remaining]


@register_model
class MassDepletion(Model):
    """Sets a body's mass, center of mass and inertia from the propellant used (config: body, engine)."""

    summary = "propellant consumption -> body mass properties in the engine (config: body, engine)"
    declarations = DEPLETION
    python_update = True
    default_period = "0.1 s"
    state_outputs = staticmethod(_held)

    def __init__(self, name: str, *, body: str | None = None, engine: str = "multibody", **kwargs):
        if body is None:
            raise ModelError(f"model {name}: MassDepletion needs config: body (the engine body whose tanks empty)")
        self.body, self.engine_name = body, engine
        super().__init__(name, **kwargs)

    def configure(self):
        full, empty = float(self.parameter("full_mass")), float(self.parameter("empty_mass"))
        if not empty < full:
            raise ModelError(f"model {self.path}: parameters empty_mass ({empty:g} kg) must be below full_mass "
                             f"({full:g} kg)")
        initial = {"mass": full, "propellant_remaining": full - empty}
        self.discrete_states = tuple(replace(d, initial=initial[d.name]) if d.name in initial else d
                                     for d in DISCRETE)
        self._system = None

    def _engine_system(self):
        simulation = self._simulation()
        index = simulation.model_index.get(self.engine_name)
        # the engine system of this run (a Monte Carlo run's context has its own mass properties)
        system = simulation.context.hosts[index] if index is not None else None
        if system is None:
            raise ModelError(f"model {self.path}: config engine: no engine model named {self.engine_name!r}")
        try:
            system.body_index(self.body)
        except Exception:
            raise ModelError(f"model {self.path}: config body: the engine has no body {self.body!r}; bodies: "
                             f"{list(system.body_names)}") from None
        return system

    def _apply(self, used: float, z) -> None:
        """Mass properties for ``used`` kg of propellant into the engine and the states (the same
        arithmetic at a sample and after a restore, so both give bit-identical mass properties)."""
        if self._system is None:
            self._system = self._engine_system()
        full, empty = float(self.parameter("full_mass")), float(self.parameter("empty_mass"))
        f = used / (full - empty)
        com = (1 - f) * self.parameter("full_com") + f * self.parameter("empty_com")
        inertia = (1 - f) * self.parameter("full_inertia") + f * self.parameter("empty_inertia")
        self._system.set_mass_properties(self.body, full - used, com, inertia)
        z[Z.mass] = full - used
        z[Z.propellant_remaining] = full - empty - used
        z[Z.propellant_used] = used

    def update(self, t, x, z, u, p):
        """Python (``python_update``): the mass properties go into the engine through its Python API."""
        full, empty = float(self.parameter("full_mass")), float(self.parameter("empty_mass"))
        self._apply(min(max(float(u[U.propellant_used]), 0.0), full - empty), z)

    def restored(self, t, x, z, p):
        # the engine still holds whatever mass it had before the restore: set the restored one now
        self._apply(float(z[Z.propellant_used]), z)
