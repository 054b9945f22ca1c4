"""The Ray executor's own tests: what it accepts as a plan, and that a task whose predecessor did
not pass is still handed to hilrig, whose verdict it reports. (The cluster itself is exercised
by tests/campaign.rs and tests/efast_interop.rs, which start one.)"""

import json
import os
import sys
import tempfile
import unittest
from unittest import mock

sys.path.insert(0, os.path.join(os.path.dirname(__file__), ".."))

from hilrig_ray.executor import PlanError, count, exit_code, load_plan, run_one  # noqa: E402


def task(id_, after=()):
    return {
        "id": id_,
        "step": "check",
        "args": ["check"],
        "inputs": [],
        "outputs": [],
        "after": list(after),
        "results": [0],
        "gates": [],
        "partial": False,
        "log": "/dev/null",
    }


class LoadPlan(unittest.TestCase):
    def write(self, plan):
        f = tempfile.NamedTemporaryFile("w", suffix=".json", delete=False)
        json.dump(plan, f)
        f.close()
        self.addCleanup(os.unlink, f.name)
        return f.name

    def plan(self, tasks, **over):
        p = {"kind": "campaign_plan", "schema": 4, "campaign": "c", "campaign_file": "/c.toml",
             "out": "/o", "files": [], "tasks": tasks}
        p.update(over)
        return p

    def test_a_plan_in_order_is_read(self):
        p = load_plan(self.write(self.plan([task("a"), task("b", ["a"])])))
        self.assertEqual([t["id"] for t in p["tasks"]], ["a", "b"])

    def test_another_kind_or_schema_is_refused(self):
        with self.assertRaisesRegex(PlanError, "kind 'check'"):
            load_plan(self.write(self.plan([], kind="check")))
        with self.assertRaisesRegex(PlanError, "schema 2"):
            load_plan(self.write(self.plan([], schema=2)))

    def test_a_task_before_what_it_waits_for_is_refused(self):
        with self.assertRaisesRegex(PlanError, "waits for a"):
            load_plan(self.write(self.plan([task("b", ["a"]), task("a")])))
        with self.assertRaisesRegex(PlanError, "twice"):
            load_plan(self.write(self.plan([task("a"), task("a")])))


class RunOne(unittest.TestCase):
    def stand_in(self, script):
        """A stand-in for hilrig that reads the plan from its standard input and runs `script`
        (sh), as hilrig answers a task."""
        d = tempfile.TemporaryDirectory()
        self.addCleanup(d.cleanup)
        fake = os.path.join(d.name, "hilrig")
        with open(fake, "w") as f:
            f.write("#!/bin/sh\ncat >/dev/null\n" + script)
        os.chmod(fake, 0o755)
        return fake

    def test_a_task_after_one_that_did_not_pass_is_still_handed_to_hilrig(self):
        # hilrig decides from the stamps that it does not run, and removes what it left in an
        # earlier run; its verdict is the outcome. A stand-in that answers as hilrig does.
        fake = self.stand_in(
            "echo '{\"task\": \"resim/m/r1\", \"outcome\": \"not_run\", "
            "\"exit\": null, \"passes\": false, \"why\": \"check/r1: exit 1\"}'\n"
            "exit 1\n"
        )
        failed = {"task": "check/r1", "outcome": "ran", "exit": 1, "passes": False}
        out = run_one(fake, "{}", "resim/m/r1", failed)
        self.assertEqual(out["outcome"], "not_run")
        self.assertIn("check/r1", out["why"])

    def test_hilrig_s_threads_are_the_task_s_cpus_unless_the_worker_sets_them(self):
        # A stand-in that answers with the pool size it was given.
        fake = self.stand_in(
            "echo '{\"task\": \"x\", \"outcome\": \"ran\", \"exit\": 0, "
            "\"passes\": true, \"why\": \"'\"${RAYON_NUM_THREADS:-unset}\"'\"}'\n"
        )
        with mock.patch.dict(os.environ):
            os.environ.pop("RAYON_NUM_THREADS", None)
            self.assertEqual(run_one(fake, "{}", "x", threads=3)["why"], "3")
            self.assertEqual(run_one(fake, "{}", "x")["why"], "unset")
            os.environ["RAYON_NUM_THREADS"] = "7"
            self.assertEqual(run_one(fake, "{}", "x", threads=3)["why"], "7")

    def test_a_hilrig_that_cannot_be_started_is_a_failure(self):
        out = run_one("/nonexistent/hilrig", "{}", "resim/m/r1")
        self.assertEqual(out["outcome"], "failed")
        self.assertIn("cannot start", out["why"])

    def test_a_summary_runs_after_a_predecessor_that_did_not_pass(self):
        # The report is partial: its command is started (here one that is not hilrig, so it
        # fails) instead of the task being stopped by its predecessor.
        not_run = {"task": "resim/m/r1", "outcome": "not_run", "exit": None, "passes": False}
        out = run_one(sys.executable, "{}", "report", not_run)
        self.assertEqual(out["outcome"], "failed")
        self.assertIn("hilrig campaign task exited", out["why"])

    def test_hilrig_that_cannot_run_the_task_is_a_failure_with_its_message(self):
        out = run_one(sys.executable, "{}", "x")
        self.assertEqual(out["outcome"], "failed")
        self.assertFalse(out["passes"])


class ExitCode(unittest.TestCase):
    def test_a_drive_that_fails_its_check_makes_the_exit_1_as_the_local_executor_s(self):
        plan = {"tasks": [task("check/r1"), task("check/r2"), dict(task("report"), step="report")]}
        ran = lambda t, e: {"task": t, "outcome": "ran", "exit": e, "passes": True}  # noqa: E731
        counts = count(plan, [ran("check/r1", 0), ran("check/r2", 1), ran("report", 1)])
        self.assertEqual(counts["checks_failed"], 1)
        self.assertEqual(counts["ran"], 3)
        self.assertEqual(exit_code(counts), 1)
        # The report's exit 1 (inputs absent) is its result, not a failed check.
        counts = count(plan, [ran("check/r1", 0), ran("check/r2", 0), ran("report", 1)])
        self.assertEqual(exit_code(counts), 0)


if __name__ == "__main__":
    unittest.main()
