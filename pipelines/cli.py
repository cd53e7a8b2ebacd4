"""The ``scioc`` command line: thin wrappers that parse options and call one pipeline function."""

from __future__ import annotations

import argparse
import json
import sys


def _cmd_loglik(args) -> int:
    from pipelines.loglik import parse_theta, study_loglik

    theta = parse_theta(args.theta)
    table = study_loglik(args.study, theta)
    if args.format == "json":
        records = [
            {"subject": r.subject, "condition": r.condition, "loglik": float(r.loglik)}
            for r in table.itertuples(index=False)
        ]
        print(json.dumps(records, indent=2))
    else:
        print(table.to_string(index=False, float_format=lambda v: f"{v:.6f}"))
    return 0


def _cmd_bench(args) -> int:
    from pipelines.bench import run_bench

    run_bench(args.json, quick=args.quick)
    if args.json:
        print(f"wrote {args.json}")
    return 0


def _cmd_assistant(args) -> int:
    from pipelines.assistant_check import assistant_alone, format_assistant

    res = assistant_alone()
    print(json.dumps(res, indent=2) if args.format == "json" else format_assistant(res))
    return 0


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="scioc",
        description="Shared-control inverse optimal control: identify human steering cost functions "
        "in manual and shared control (Inga et al., SMC 2018).",
    )
    sub = parser.add_subparsers(dest="command", required=True)

    p = sub.add_parser("loglik", help="max-ent log-likelihood of every segment of a study file under one θ")
    p.add_argument("study", help="study file (Parquet or CSV) in the data convention")
    p.add_argument("--theta", required=True, help="q11,q22,R (e.g. 60,0,1)")
    p.add_argument("--format", choices=("table", "json"), default="table")
    p.set_defaults(func=_cmd_loglik)

    p = sub.add_parser("assistant", help="the MPC assistant alone on the study reference: tracking and torques")
    p.add_argument("--format", choices=("table", "json"), default="table")
    p.set_defaults(func=_cmd_assistant)

    p = sub.add_parser("bench", help="measured speed of the kernels")
    p.add_argument("--json", metavar="PATH", help="also write the results as JSON")
    p.add_argument("--quick", action="store_true", help="small sizes, to check the command (numbers not quotable)")
    p.set_defaults(func=_cmd_bench)
    return parser


def main(argv=None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return args.func(args)
    except (ValueError, OSError) as exc:
        print(f"scioc {args.command}: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
