"""``flexshell slosh``: pendulum slosh bodies for a scenario from a cylindrical tank's fill level.

Computes the mechanical equivalents of :func:`dynamics.slosh_tank.cylindrical_tank_slosh` and prints
the scenario YAML: one U-joint pendulum body per mode (hinge at the pressure resultant, bob at the
pendulum length below it) and the ``SloshSpringDamper`` giving the liquid's damping ratio
(``c = 2 zeta m L^2 omega``); the rigid remainder of the liquid is reported for the tank body's mass
properties. The tank axis is the parent body's +z, its bottom centre at ``--bottom``.
"""

from __future__ import annotations

import sys


def register(subparsers) -> None:
    parser = subparsers.add_parser(
        "slosh", help="pendulum slosh bodies (scenario YAML) from a cylindrical tank's fill level",
        description="Slosh pendulum parameters of an upright flat-bottomed cylindrical tank from its fill "
                    "level (potential flow; Abramson SP-106, Dodge 2000), printed as scenario YAML.")
    parser.add_argument("--radius", required=True, help='tank radius, e.g. "1.5 m"')
    parser.add_argument("--fill", required=True, help='liquid depth, e.g. "2 m"')
    parser.add_argument("--density", required=True, help='liquid density, e.g. "1140 kg/m^3"')
    parser.add_argument("--acceleration", required=True, help='axial acceleration, e.g. "30 m/s^2"')
    parser.add_argument("--modes", type=int, default=1, help="lateral modes (pendulums), default 1")
    parser.add_argument("--damping-ratio", type=float, default=0.01, help="liquid damping ratio, default 0.01")
    parser.add_argument("--parent", default="stage", help="tank body (default stage)")
    parser.add_argument("--bottom", default="[0, 0, 0] m", help='tank bottom centre in the parent, "[x, y, z] m"')
    parser.add_argument("--name", default="slosh", help="slosh body name prefix (default slosh)")
    parser.set_defaults(func=slosh)


def slosh(args) -> int:
    import numpy as np

    from dynamics.slosh_tank import cylindrical_tank_slosh
    from shell.units import UnitError, to_magnitude

    try:
        radius = float(to_magnitude(args.radius, "m", (), "--radius"))
        fill = float(to_magnitude(args.fill, "m", (), "--fill"))
        density = float(to_magnitude(args.density, "kg/m^3", (), "--density"))
        acceleration = float(to_magnitude(args.acceleration, "m/s^2", (), "--acceleration"))
        bottom = to_magnitude(args.bottom, "m", (3,), "--bottom")
        tank = cylindrical_tank_slosh(radius, fill, density, acceleration, args.modes)
    except (UnitError, ValueError) as exc:
        print(f"flexshell slosh: {exc}", file=sys.stderr)
        return 1
    print(f"# cylindrical tank R = {radius:g} m, liquid depth {fill:g} m, {tank.liquid_mass:.6g} kg, "
          f"a = {acceleration:g} m/s^2 (flexshell slosh)")
    print(f"# rigid part of the liquid: {tank.fixed_mass:.6g} kg at {tank.fixed_height:.6g} m above the "
          "bottom: add it to the tank body's mass properties")
    bodies, models = [], []
    for n in range(args.modes):
        name = args.name if args.modes == 1 else f"{args.name}{n + 1}"
        m, length, omega = tank.slosh_masses[n], tank.pendulum_lengths[n], tank.frequencies[n]
        hinge = bottom + np.array([0.0, 0.0, tank.hinge_heights[n]])
        damping = 2.0 * args.damping_ratio * m * length**2 * omega
        bodies.append(
            f"    - {{name: {name}, parent: {args.parent}, hinge: ujoint, axes: [[1, 0, 0], [0, 1, 0]],\n"
            f"       mass: {m:.9g} kg, com: \"[0, 0, {-length:.9g}] m\", inertia: \"[1e-6, 1e-6, 1e-6] kg*m^2\",\n"
            f"       inboard_position: \"[{hinge[0]:.9g}, {hinge[1]:.9g}, {hinge[2]:.9g}] m\"}}"
            f"   # mode {n + 1}: {tank.frequencies_hz[n]:.6g} Hz")
        models.append(f"  {name}_damper: {{type: SloshSpringDamper, attach: {{hinge: {name}}}, "
                      f"parameters: {{damping: \"[{damping:.9g}, {damping:.9g}] N*m*s/rad\"}}}}")
    print("multibody:\n  bodies:\n" + "\n".join(bodies))
    print("models:\n" + "\n".join(models))
    return 0
