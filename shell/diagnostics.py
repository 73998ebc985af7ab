"""One channel for the warnings a user's inputs earn (issue 34): scenario, campaign and deck diagnostics reach
the user as ``flexshell VERB: warning: FILE:LINE: KEY: what`` (each once), never as Python's
``multibody.py:569: UserWarning: ...`` followed by a line of flexshell's source.

Two pieces:

* :func:`located` wraps the building of one part of a scene (a body, a model) whose code knows no file (the
  engine, a model's constructor): the warnings raised inside are raised again with the part's location
  (``scene.yaml:12: multibody.bodies[0](bus)``) in front;
* :func:`printed` is installed by the command line (:func:`shell.cli.main`) around every verb: it prints each
  warning once, as a flexshell message on stderr; DeprecationWarning and its kin (a library's business, not
  the user's) are not shown, as Python does by default.

What is refused and what is warned (CONVENTIONS: refuse what cannot be meant, warn what is allowed but
suspicious):

* refused: a rigid inertia whose principal moments violate the triangle inequality I1 + I2 >= I3. It holds
  for every mass distribution (I1 + I2 - I3 = 2 * integral of z^2 dm >= 0, z along the third principal axis),
  so a violation is no body at all: a typing slip, moments of another body or frame, a wheel's spin inertia
  given without its transverse inertia. MuJoCo's compiler (unless asked to balance the inertia) and Drake
  (SpatialInertia::IsPhysicallyValid) refuse it as well; the motion computed for it would be that of nothing
  that exists. Also refused, as before: an inertia that is not symmetric positive semi-definite, a singular one
  where the hinge needs it.
* warned: choices that are legal and sometimes meant: modes dropped by ``max_frequency``, normalized component
  modes mounted where their interface is not held, a flexible body's notes (terms left out), a Profile that
  jumps after its last breakpoint, a deck's unsupported cards with ``--allow-unsupported``, a damping ratio of
  1 or more, a flexible mode below ``--rigid-threshold``, a singular central inertia (accepted where no hinge
  needs it), an integrator's stiffness detection during a run.
"""

from __future__ import annotations

import contextlib
import sys
import warnings

#: warnings that concern a library's future, not the user's inputs (hidden, as Python hides them by default)
HIDDEN = (DeprecationWarning, PendingDeprecationWarning, ImportWarning, ResourceWarning)


@contextlib.contextmanager
def located(where):
    """Raise the warnings of the enclosed block again with ``where`` (a scenario location: ``file:line: key``,
    or a function of the message giving it) in front, unless they already name the file."""
    caught: list = []
    try:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            yield
    finally:  # also when the block is refused: its warnings may say why
        for warning in caught:
            if not issubclass(warning.category, HIDDEN):
                text = str(warning.message)
                here = where(text) if callable(where) else where
                file = str(getattr(here, "file", here)).split(":", 1)[0]
                warnings.warn(text if text.startswith(file) else f"{here}: {text}", warning.category)


@contextlib.contextmanager
def printed(prefix: str, stream=None):
    """Print every warning of the enclosed block once as ``PREFIX: warning: message`` on ``stream`` (stderr)."""
    seen = set()

    def show(message, category, filename, lineno, file=None, line=None):
        text = str(message)
        if text not in seen:
            seen.add(text)
            print(f"{prefix}: warning: {text}", file=stream or sys.stderr, flush=True)

    with warnings.catch_warnings():
        warnings.simplefilter("always")  # each message once: by its text, here, not once per source line
        for category in HIDDEN:
            warnings.simplefilter("ignore", category)
        warnings.showwarning = show
        yield
