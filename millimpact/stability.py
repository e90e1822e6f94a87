"""``millimpact stability``: map where each time integrator fails (not available yet)."""
from __future__ import annotations

import argparse

HELP = "map where each time integrator fails (not available yet)"


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("rest", nargs="*")
    p.add_argument("--out")


def main(args: argparse.Namespace) -> int:
    from .cli import cmd_not_yet

    return cmd_not_yet(args)
