"""Runs a hilrig campaign plan (`hilrig campaign plan --json`) on a Ray cluster.

Each task of the plan becomes one Ray task that runs `hilrig campaign task --plan PLAN ID` on a
worker node; the tasks it waits for are passed as Ray object references, so Ray starts it only
when they are done. hilrig does the rest as the local executor does: a task whose predecessors
did not pass is not run, a task that is up to date is skipped, a finished task leaves its stamp.
A worker lost mid-task (a node that dies, a process killed) is a system failure that Ray retries
on another node; the retry finds no stamp and runs the task again.
"""

from .executor import load_plan, run

__all__ = ["load_plan", "run"]
