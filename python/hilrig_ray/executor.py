"""The Ray executor: a plan's tasks as Ray tasks, each one `hilrig campaign task` on a worker.

usage: python -m hilrig_ray PLAN.json [--address ADDRESS] [--hilrig PATH] [--retries N]
"""

import argparse
import json
import os
import subprocess
import sys

PLAN_KIND = "campaign_plan"
PLAN_SCHEMA = 4


class PlanError(ValueError):
    """A file that is not a plan this executor reads."""


def load_plan(path):
    """The plan at `path`, checked: its kind and schema, and every task after those it waits for."""
    with open(path, encoding="utf-8") as f:
        plan = json.load(f)
    if plan.get("kind") != PLAN_KIND:
        raise PlanError(f"{path}: kind {plan.get('kind')!r}, not {PLAN_KIND!r}")
    if plan.get("schema") != PLAN_SCHEMA:
        raise PlanError(
            f"{path}: plan schema {plan.get('schema')}, but this executor reads schema "
            f"{PLAN_SCHEMA}: use the hilrig-ray of the hilrig that wrote it"
        )
    seen = set()
    for task in plan["tasks"]:
        for dep in task["after"]:
            if dep not in seen:
                raise PlanError(f"{path}: task {task['id']} waits for {dep}, which is not before it")
        if task["id"] in seen:
            raise PlanError(f"{path}: task {task['id']} twice")
        seen.add(task["id"])
    return plan


def run_one(hilrig, plan_text, task_id, *before):
    """One task on this worker, once the tasks it waits for have ended (`before`: their
    outcomes, passed as Ray object references for the ordering). The plan comes as text
    (standard input of `hilrig campaign task --plan -`), so that a worker needs no disk shared
    with the head: a campaign whose files are in a bucket runs on any node.

    hilrig decides from the stamps whether the tasks before it passed (a `partial` task, the
    report, runs whatever their outcomes), and a task that does not run removes what it left in
    an earlier run, so that the report does not show it as this run's: it is asked even when
    a task before it failed here."""
    del before
    try:
        proc = subprocess.run(
            [hilrig, "campaign", "task", "--plan", "-", task_id],
            input=plan_text,
            capture_output=True,
            text=True,
            check=False,
        )
    except OSError as e:
        return {
            "task": task_id,
            "outcome": "failed",
            "exit": None,
            "passes": False,
            "why": f"cannot start {hilrig}: {e}",
        }
    lines = proc.stdout.strip().splitlines()
    if proc.returncode not in (0, 1) or not lines:
        return {
            "task": task_id,
            "outcome": "failed",
            "exit": None,
            "passes": False,
            "why": f"hilrig campaign task exited {proc.returncode}: {proc.stderr.strip()[-500:]}",
        }
    outcome = json.loads(lines[-1])
    outcome["pid"] = os.getpid()
    return outcome


def run(plan_path, hilrig="hilrig", address=None, retries=3):
    """Runs every task of the plan on the cluster at `address` (None: start a local one);
    returns their outcomes in the plan's order."""
    import ray

    plan_path = os.path.abspath(plan_path)
    plan = load_plan(plan_path)
    with open(plan_path, encoding="utf-8") as f:
        plan_text = f.read()
    package = os.path.dirname(os.path.abspath(__file__))
    ray.init(address=address, runtime_env={"py_modules": [package]}, log_to_driver=False)
    try:
        # Retried on system failures only (a worker or node lost): a task that fails in
        # hilrig fails the same way on any node, and says so in its outcome.
        remote = ray.remote(max_retries=retries, retry_exceptions=False, num_cpus=1)(run_one)
        plan_ref = ray.put(plan_text)
        refs = {}
        for task in plan["tasks"]:
            deps = [refs[d] for d in task["after"]]
            refs[task["id"]] = remote.remote(
                hilrig, plan_ref, task["id"], *deps
            )
        return ray.get([refs[t["id"]] for t in plan["tasks"]])
    finally:
        ray.shutdown()


def main(argv=None):
    p = argparse.ArgumentParser(prog="hilrig-ray", description=__doc__.splitlines()[0])
    p.add_argument("plan", help="the plan: DIR/campaign/plan.json or `hilrig campaign plan --json`")
    p.add_argument("--address", default=None, help="the cluster (auto, or HOST:PORT); default: a new local one")
    p.add_argument("--hilrig", default="hilrig", help="the hilrig executable on the workers")
    p.add_argument("--retries", type=int, default=3, help="retries of a task whose worker was lost")
    args = p.parse_args(argv)
    try:
        plan = load_plan(os.path.abspath(args.plan))
        outcomes = run(args.plan, args.hilrig, args.address, args.retries)
    except PlanError as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    for o in outcomes:
        if o["outcome"] in ("failed", "not_run"):
            print(f"  {o['outcome']:<8} {o['task']}: {o.get('why')}")
    counts = count(plan, outcomes)
    print(json.dumps({"outcomes": outcomes, "counts": counts}))
    return exit_code(counts)


def count(plan, outcomes):
    """Tasks per outcome, and `checks_failed`: the drives whose check ran and failed them
    (exit 1, a result the tasks after it may read, but one the user must see)."""
    counts = {"checks_failed": 0}
    for t, o in zip(plan["tasks"], outcomes):
        counts[o["outcome"]] = counts.get(o["outcome"], 0) + 1
        if t["step"] == "check" and o.get("exit") == 1:
            counts["checks_failed"] += 1
    return counts


def exit_code(counts):
    """0 when every task has a result that lets the tasks after it run and every drive passed
    its check; 1 otherwise (as `hilrig campaign` exits)."""
    bad = counts.get("failed", 0) + counts.get("not_run", 0) + counts["checks_failed"]
    return 0 if bad == 0 else 1


if __name__ == "__main__":
    sys.exit(main())
