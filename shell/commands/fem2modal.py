"""``flexshell fem2modal``: NASTRAN bulk data (or OP4 + geometry deck) to an HDF5 body file."""

from __future__ import annotations

import argparse
import sys

from shell.outputs import OVERWRITE_HELP


def register(subparsers) -> None:
    p = subparsers.add_parser(
        "fem2modal",
        help="turn a NASTRAN bulk-data deck into an HDF5 flexible-body file",
        description="FEM-to-modal pipeline (FModal equivalent): free-free normal modes, or "
                    "Craig-Bampton and normalized component modes for an a-set; residual "
                    "vectors, rigid-body mass properties, modal integrals. See docs/fem2modal.md.")
    p.add_argument("deck", help="bulk data deck (.dat/.bdf; INCLUDE files are followed)")
    count = p.add_mutually_exclusive_group(required=True)
    count.add_argument("--modes", type=int, metavar="N",
                       help="number of flexible modes (fixed-interface modes with --aset)")
    count.add_argument("--cutoff", type=float, metavar="HZ",
                       help="keep every mode up to this frequency [Hz]")
    p.add_argument("--aset", action="append", default=[], metavar="GRID:DOFS",
                   help="interface DOFs (e.g. 1:123456); repeatable. Gives normalized "
                        "component modes and a Craig-Bampton model")
    p.add_argument("--residual", action="append", default=[], metavar="GRID:DOFS",
                   help="load DOFs for residual vectors; repeatable")
    p.add_argument("--grdpnt", type=int, metavar="G",
                   help="reference grid for mass properties and the body frame "
                        "(default: PARAM GRDPNT, else the basic origin)")
    p.add_argument("--modal-integrals", action="store_true",
                   help="compute the modal integrals of TM-2020-5008164 App. E")
    p.add_argument("--geometric-stiffness", action="store_true",
                   help="also store the modal geometric stiffness of the rigid-motion load cases "
                        "(stiffening of spinning or accelerating bodies; docs/geometric_stiffening.md)")
    p.add_argument("--preload", action="append", default=[], metavar="NAME:GRID:COMP:VALUE",
                   help="named static load (component 1-3 force N, 4-6 moment N m, basic axes) whose "
                        "geometric stiffness is stored (a scene scales it); repeatable, entries with "
                        "one NAME add up; implies --geometric-stiffness")
    p.add_argument("--separate-lumped", action="store_true",
                   help="take CONM2 masses out of the body and store them as child rigid bodies")
    p.add_argument("--damping", type=float, default=0.0, metavar="ZETA",
                   help="uniform modal damping ratio (default 0)")
    p.add_argument("--rigid-threshold", type=float, default=None, metavar="HZ",
                   help="warn when a flexible mode is below this frequency; rigid-body modes "
                        "themselves come from the geometry (see docs/fem2modal.md)")
    p.add_argument("--op4", metavar="FILE",
                   help="take KGG and MGG from this OP4 file; the deck supplies grids and "
                        "constraints")
    p.add_argument("--units", metavar="LENGTH,FORCE,TIME",
                   help="the deck's unit system, e.g. in,lbf,s; mm,N,s; mm,kg,s (LENGTH,MASS,TIME); the body "
                        "file is written in SI and records the conversion; PARAM WTMASS still applies "
                        "(default: the deck is SI; --preload values are SI either way)")
    p.add_argument("--csid", type=int, metavar="CID",
                   help="output coordinate system (rectangular): the body frame takes its axes, origin at "
                        "the reference grid (default 0: basic axes)")
    p.add_argument("--op2", metavar="FILE",
                   help="NASTRAN OP2 results: its SOL 103 eigenvalues and eigenvectors (OUGV1/BOUGV1) are the "
                        "body's modes, normalized with the deck's mass and checked against our own; without "
                        "eigenvectors, its KGG and MGG replace the assembled matrices")
    p.add_argument("--recover-elements", action="append", default=[], metavar="EID[,EID...]",
                   help="loads recovery: element forces and stresses of these CBAR/CBEAM/CROD elements by mode "
                        "displacement and mode acceleration, for the LoadsRecovery model; repeatable")
    p.add_argument("--recover-grids", action="append", default=[], metavar="GRID[,GRID...]",
                   help="loads recovery: interface forces at these grids; repeatable")
    p.add_argument("--gset", action="store_true", help="store the G-set sparse K and M")
    p.add_argument("--fset", action="store_true", help="store the F-set sparse K and M")
    p.add_argument("--modal-matrix", action="store_true",
                   help="store the full g-set modal matrix")
    p.add_argument("--allow-unsupported", action="store_true",
                   help="proceed (with a warning) when the deck has structural cards that are "
                        "not modelled")
    p.add_argument("-q", "--quiet", action="store_true", help="no progress messages")
    p.add_argument("-o", "--output", required=True, metavar="BODY.h5", help="body file to write")
    p.add_argument("--overwrite", action="store_true", help=OVERWRITE_HELP)
    p.set_defaults(func=run)


def _ids(items, flag):
    """[int] of repeatable comma-separated ids; ValueError naming the flag."""
    out = []
    for item in items:
        for text in str(item).split(","):
            try:
                out.append(int(text))
            except ValueError:
                raise ValueError(f"{flag}: expected integer ids separated by commas, got {item!r}") from None
    return out


def run(args: argparse.Namespace) -> int:
    from dynamics.flex.body_file import write_body_file
    from dynamics.flex.bulk_data import BulkDataError
    from dynamics.flex.component_modes import CraigBamptonError
    from dynamics.flex.geometric_stiffness import parse_preload
    from dynamics.flex.modes import EigenSolutionError
    from dynamics.flex.pipeline import Fem2ModalOptions, fem2modal, parse_grid_dofs
    from shell.outputs import BODY_FILE, guard_output

    def progress(msg):
        if not args.quiet:
            print(msg, file=sys.stderr, flush=True)

    try:
        guard_output(args.output, BODY_FILE, inputs=((args.deck, "the deck itself"), (args.op4, "the OP4 file"),
                                                     (args.op2, "the OP2 file")),
                     overwrite=args.overwrite)
        options = Fem2ModalOptions(
            n_modes=args.modes, cutoff_hz=args.cutoff,
            aset=[parse_grid_dofs(s) for s in args.aset],
            residual=[parse_grid_dofs(s) for s in args.residual],
            grdpnt=args.grdpnt, modal_integrals=args.modal_integrals,
            separate_lumped=args.separate_lumped, damping=args.damping,
            rigid_threshold_hz=args.rigid_threshold, write_gset=args.gset,
            write_fset=args.fset, write_modal_matrix=args.modal_matrix,
            allow_unsupported=args.allow_unsupported, op4=args.op4,
            geometric_stiffness=args.geometric_stiffness,
            preloads=[parse_preload(s) for s in args.preload], units=args.units, csid=args.csid,
            op2=args.op2, recover_elements=_ids(args.recover_elements, "--recover-elements"),
            recover_grids=_ids(args.recover_grids, "--recover-grids"))
        body = fem2modal(args.deck, options, progress=progress)  # its warnings: flexshell messages (shell.cli)
        write_body_file(args.output, body)
    except (BulkDataError, CraigBamptonError, EigenSolutionError, ValueError,
            FileNotFoundError) as exc:
        print(f"flexshell fem2modal: error: {exc}", file=sys.stderr)
        return 1
    first = ", ".join(f"{f:.6g}" for f in body.frequencies_hz[:6])
    mass = f"{body.mass:.6g} kg"
    if body.deck_units is not None:
        from dynamics.flex.units import parse_units
        units = parse_units(body.deck_units["spec"])
        mass += f" ({body.mass / units.mass:.6g} {units.mass_name} in the deck's units {units.spec})"
    if body.mode_set == "normalized-component":
        fixed = ", ".join(f"{f:.6g}" for f in body.craig_bampton.frequencies_hz[:6])
        progress(f"wrote {args.output}: {body.n_modes} normalized component modes, mass "
                 f"{mass}; fixed-interface frequencies (interface grids "
                 f"{body.interface_grids()} held) [Hz]: {fixed}; free-free frequencies of the "
                 f"unmounted component [Hz]: {first} (neither is the mounted body's spectrum, "
                 "which depends on the hinge: mount with child_grid on an interface grid)")
    else:
        progress(f"wrote {args.output}: {body.n_modes} free-free modes, mass {mass}, "
                 f"first flexible frequencies [Hz]: {first}")
    return 0
