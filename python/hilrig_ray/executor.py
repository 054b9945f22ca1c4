"""The Ray executor: a plan's tasks as Ray tasks, each one `hilrig campaign task` on a worker.

usage: python -m hilrig_ray PLAN.json [--address ADDRESS] [--hilrig PATH] [--retries N]
                              [--cpus-per-task N]
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
    return read_plan(path)[0]


def read_plan(path):
    """The plan at `path`, checked (see `load_plan`), and its text as the tasks are given it."""
    with open(path, encoding="utf-8") as f:
        text = f.read()
    plan = json.loads(text)
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
    return plan, text


def run_one(hilrig, plan_text, task_id, *before, threads=None):
    """One task on this worker, once the tasks it waits for have ended (`before`: their
    outcomes, passed as Ray object references for the ordering). The plan comes as text
    (standard input of `hilrig campaign task --plan -`), so that a worker needs no disk shared
    with the head: a campaign whose files are in a bucket runs on any node.

    hilrig decides from the stamps whether the tasks before it passed (a `partial` task, the
    report, runs whatever their outcomes), and a task that does not run removes what it left in
    an earlier run, so that the report does not show it as this run's: it is asked even when
    a task before it failed here.

    `threads`: the CPUs Ray gave the task. hilrig's own work runs on a pool of one thread per
    core unless `RAYON_NUM_THREADS` says otherwise; on a node of 32 cores that would be 32
    threads for each of the 32 tasks Ray places there, so the pool is sized to the task's
    share (as Ray sizes `OMP_NUM_THREADS`), unless the worker's environment sets it."""
    del before
    env = None
    if threads is not None:
        env = dict(os.environ)
        env.setdefault("RAYON_NUM_THREADS", str(max(1, int(threads))))
    try:
        proc = subprocess.run(
            [hilrig, "campaign", "task", "--plan", "-", task_id],
            input=plan_text,
            capture_output=True,
            text=True,
            check=False,
            env=env,
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
    outcome["node"] = node_id()
    return outcome


def node_id():
    """The Ray node this runs on (hex), or None outside a Ray task."""
    try:
        import ray
    except ImportError:
        return None
    if not ray.is_initialized():
        return None
    return ray.get_runtime_context().get_node_id()


def run(plan_path, hilrig="hilrig", address=None, retries=3, cpus_per_task=1):
    """Runs every task of the plan on the cluster at `address` (None: start a local one),
    each with `cpus_per_task` CPUs; returns their outcomes in the plan's order."""
    plan, plan_text = read_plan(os.path.abspath(plan_path))
    return run_plan(plan, plan_text, hilrig, address, retries, cpus_per_task)


def run_plan(plan, plan_text, hilrig="hilrig", address=None, retries=3, cpus_per_task=1):
    """`run` of a plan already read (`read_plan`)."""
    import ray

    package = os.path.dirname(os.path.abspath(__file__))
    ray.init(address=address, runtime_env={"py_modules": [package]}, log_to_driver=False)
    try:
        # Retried on system failures only (a worker or node lost): a task that fails in
        # hilrig fails the same way on any node, and says so in its outcome.
        remote = ray.remote(
            max_retries=retries, retry_exceptions=False, num_cpus=cpus_per_task
        )(run_one)
        plan_ref = ray.put(plan_text)
        refs = {}
        for task in plan["tasks"]:
            deps = [refs[d] for d in task["after"]]
            refs[task["id"]] = remote.remote(
                hilrig, plan_ref, task["id"], *deps, threads=cpus_per_task
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
    p.add_argument(
        "--cpus-per-task",
        type=int,
        default=1,
        help="CPUs Ray reserves for each task, and the threads hilrig uses in it",
    )
    args = p.parse_args(argv)
    if args.cpus_per_task < 1:
        print(f"error: --cpus-per-task {args.cpus_per_task}: at least 1", file=sys.stderr)
        return 2
    try:
        plan, text = read_plan(os.path.abspath(args.plan))
        outcomes = run_plan(plan, text, args.hilrig, args.address, args.retries, args.cpus_per_task)
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
