"""What ``capture`` and ``resume`` share once a run is under way: the progress line while
it runs, the devices or the run store out of reach (exit 1), the outcome printed
(:mod:`presentation.run_outcome`; under ``--json`` with the run's ``log`` file:
:class:`cellcal.logs.RunLog`) and its exit code."""

from __future__ import annotations

import sys


def with_progress(command: str, as_json: bool, go):
    """``go(progress)`` (a use case that may run a capture) with a progress line on stderr
    (none under ``--json``): ``(result, None)``, or ``(None, 1)`` after saying that the
    devices or the run store cannot be reached."""
    from daq.errors import ConnectFailed
    from daq.store import StoreUnavailable

    from ..progress import Progress

    progress = Progress(enabled=not as_json)
    try:
        return go(progress), None
    except ConnectFailed as e:
        print(f"cellcal {command}: cannot connect: {e}", file=sys.stderr)
        return None, 1
    except StoreUnavailable as e:
        print(f"cellcal {command}: run store unreachable: {e}; `cellcal resume` once it is "
              "back", file=sys.stderr)
        return None, 1
    finally:
        progress.close()


def print_outcome(outcome, as_json: bool, log_path=None) -> int:
    """Print a run outcome (``RunOutcome``: JSON or text; the JSON names the run's log file,
    ``log_path``, null when none was written); its exit code."""
    from presentation.run_outcome import outcome_exit_code, outcome_lines

    from .common import print_json

    out = outcome.to_json()
    if as_json:
        print_json({**out, "log": None if log_path is None else str(log_path)})
    else:
        print("\n".join(outcome_lines(out)))
    return outcome_exit_code(out)
