"""Settings for the whole suite.

Ctrl-C reaches the child processes that tests interrupt (test_interrupt, test_run_again,
test_viz_cli). A shell without job control (``pytest ... &`` in a script, ``nohup``, some CI
runners) starts a background command with SIGINT *ignored*; its children inherit that, Python
then installs no ``KeyboardInterrupt`` handler, and the child runs on through the test's Ctrl-C
to exit 0. Catching SIGINT here instead (Python's own handler, as in any interactive run) means
children start with the default action again (exec resets caught signals, never ignored ones).
"""

from __future__ import annotations

import signal

if signal.getsignal(signal.SIGINT) is signal.SIG_IGN:
    signal.signal(signal.SIGINT, signal.default_int_handler)
