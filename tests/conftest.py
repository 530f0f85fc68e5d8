"""Settings for the whole suite.

Ctrl-C reaches the child processes that tests interrupt (test_interrupt, test_run_again,
test_viz_cli). A shell without job control (``pytest ... &`` in a script, ``nohup``, some CI
runners) starts a background command with SIGINT *ignored*; its children inherit that, Python
then installs no ``KeyboardInterrupt`` handler, and the child runs on through the test's Ctrl-C
to exit 0. Catching SIGINT here instead (Python's own handler, as in any interactive run) means
children start with the default action again (exec resets caught signals, never ignored ones).

Hypothesis runs without deadlines (the profile ``busy-machine``): no test depends on wall-clock
timing. Dask's loopback connections get minutes, not its default 30 s, for the same reason.
"""

from __future__ import annotations

import os
import signal

from hypothesis import settings

if signal.getsignal(signal.SIGINT) is signal.SIG_IGN:
    signal.signal(signal.SIGINT, signal.default_int_handler)

# No hypothesis deadline anywhere: the suite runs on busy shared machines, where an example's
# wall time says nothing about the code (a 200 ms deadline failed test_spec under load). Examples
# that launch kernels set deadline=None themselves too.
settings.register_profile("busy-machine", deadline=None)
settings.load_profile("busy-machine")

# A Dask client or worker that waits 30 s (the default) for a loopback reply fails a test when the
# machine is loaded enough (scheduler-connection-lost at a load of 18 on 2 cores). Environment
# variables reach dask in this process and in every process a test starts (workers, benchmarks).
for _name in ("CONNECT", "TCP"):
    os.environ.setdefault(f"DASK_DISTRIBUTED__COMM__TIMEOUTS__{_name}", "300s")
