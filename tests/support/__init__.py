"""Helpers shared by the tests of every room (not a test module), one module per job:

* :mod:`.launching`: the command line (in a fresh process or in this one), the benchmarks, and
  their refusals;
* :mod:`.archives`: what an archive holds, its rows while written, the documented layout;
* :mod:`.damage`: copies with one flipped bit, and what the readers make of each;
* :mod:`.runs`: states, sweep rows and histories compared bit for bit.

Import with ``from support import ...`` (pytest puts ``tests/`` on ``sys.path``).
"""

from .archives import (
    ARCHIVE_DOC,
    DATASET_ATTRS,
    archive_contents,
    archive_rows,
    documented_names,
    documented_optional,
    no_temporaries,
    same_contents,
    written_names,
)
from .damage import archive_flip_census, flip_bit, flip_sample, stored_chunks, sweep_flip_census
from .launching import (
    MAP_FLAGS,
    USAGE_WIDTH,
    assert_one_line_error,
    benchmark,
    cli,
    error_line,
    in_process,
    launch,
    quick_benchmark,
    refused,
    run_argv,
)
from .runs import Capture, bits, exact_rows, same_history, same_state

__all__ = [
    "ARCHIVE_DOC",
    "DATASET_ATTRS",
    "MAP_FLAGS",
    "USAGE_WIDTH",
    "Capture",
    "archive_contents",
    "archive_flip_census",
    "archive_rows",
    "assert_one_line_error",
    "benchmark",
    "bits",
    "cli",
    "documented_names",
    "documented_optional",
    "error_line",
    "exact_rows",
    "flip_bit",
    "flip_sample",
    "in_process",
    "launch",
    "no_temporaries",
    "quick_benchmark",
    "refused",
    "run_argv",
    "same_contents",
    "same_history",
    "same_state",
    "stored_chunks",
    "sweep_flip_census",
    "written_names",
]
