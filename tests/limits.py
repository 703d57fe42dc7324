"""Safety nets of the tests, none of them a verdict on speed.

No assertion depends on the clock: a wall-clock timeout only ends a process that hangs without
using CPU (a deadlock). It is far above anything a run takes, even on a machine loaded many
times over; hangs that do use CPU are caught by CPU-time limits (tests/hostile_driver.py,
tests/fuzzing.py), which the load of other programs does not touch.
"""

DEADLOCK = 1800.0
"""Wall-clock seconds after which a subprocess of the tests is taken to be deadlocked."""
