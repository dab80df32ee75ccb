"""The ant-like STC robot's controller as portable C firmware: check it against the Python
controller, and build it for a microcontroller.

  stcvision firmware check [--fsm c|firmware] [--boards 500] [--pairs 1000000] [--maps F,...]
  stcvision firmware build --mcu atmega328p --out DIR [--force] [--json]

check runs the C controller (c: built here by cc; firmware: built for the microcontroller and
run in its emulator) beside the Python step on every tick of random oracle tours (any start
sub-cell and heading) and of the map files, and on random (state, reading) pairs drawn over the
whole input space; exit 0 when every tick and pair is the same, 3 when one differs. build
compiles the firmware with the cross compiler and reports its flash, its RAM (data + bss + the
stack's high-water mark, measured in the emulator) and the state's size.
"""

from __future__ import annotations

from stcvision.cli._args import seed

NESTED = True  # --json belongs to each action


def add_parser(p):
    import argparse

    from stcvision.limits import MAX_CHECK_BOARDS, MAX_CHECK_PAIRS

    p.formatter_class = argparse.RawDescriptionHelpFormatter
    sub = p.add_subparsers(dest="action", metavar="{check,build}", parser_class=type(p), required=True)
    c = sub.add_parser("check", help="the C controller against the Python one, tick by tick")
    c.add_argument("--fsm", choices=("c", "firmware"), default="c", help="the controller checked (default c)")
    c.add_argument("--mcu", default=None, metavar="NAME", help="--fsm firmware: the microcontroller")
    c.add_argument(
        "--boards",
        type=_count(MAX_CHECK_BOARDS, "MAX_CHECK_BOARDS"),
        default=500,
        metavar="N",
        help=f"random oracle boards (default 500, at most {MAX_CHECK_BOARDS:,}; 0: none)",
    )
    c.add_argument(
        "--pairs",
        type=_count(MAX_CHECK_PAIRS, "MAX_CHECK_PAIRS"),
        default=1_000_000,
        metavar="N",
        help=f"random (state, reading) pairs (default 1,000,000, at most {MAX_CHECK_PAIRS:,}; 0: none)",
    )
    c.add_argument("--maps", default=None, metavar="F,...", help="map files toured too (text or PNG)")
    c.add_argument("--seed", type=seed, default=0, help="seed of the boards and the pairs (default 0)")
    c.add_argument("--json", action="store_true", help="print the result as one JSON object")
    b = sub.add_parser("build", help="build the firmware for a microcontroller and measure it")
    b.add_argument("--mcu", default=None, metavar="NAME", help="the microcontroller (default atmega328p)")
    b.add_argument("--out", required=True, metavar="DIR", help="folder for the ELF, the hex and build.json")
    b.add_argument("--force", action="store_true", help="replace the files in --out")
    b.add_argument("--json", action="store_true", help="print the result as one JSON object")


def _count(cap: int, why: str):
    """argparse type: an integer from 0 to ``cap``."""
    import argparse

    def parse(text: str) -> int:
        try:
            v = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{text!r} is not an integer") from None
        if not 0 <= v <= cap:
            raise argparse.ArgumentTypeError(f"{text!r} must be 0 to {cap:,} ({why})")
        return v

    return parse


def run(args):
    if args.action == "check":
        from stcvision.controllers.stc.firmware_report import identity_report

        if args.mcu and args.fsm != "firmware":
            from stcvision.errors import BadInputError

            raise BadInputError("--mcu names the chip of --fsm firmware")
        maps = [m for m in args.maps.split(",") if m] if args.maps else []
        r = identity_report(args.fsm, boards=args.boards, pairs=args.pairs, maps=maps, seed=args.seed, mcu=args.mcu)
        from stcvision.cli import EXIT_INCOMPLETE, EXIT_OK

        r["exit_code"] = EXIT_OK if r["identical"] else EXIT_INCOMPLETE
        return r
    from stcvision.controllers.stc.firmware_report import build_firmware

    return build_firmware(args.mcu, args.out, overwrite=args.force)


def format_text(r) -> str:
    if "flash_bytes" in r:
        return "\n".join(
            [
                f"firmware for {r['mcu']}: {r['elf']}",
                f"flash {r['flash_bytes']:,} of {r['flash_capacity']:,} bytes; RAM {r['ram_bytes']:,} of "
                f"{r['ram_capacity']:,} (data {r['data_bytes']}, bss {r['bss_bytes']}, stack high-water "
                f"{r['stack_bytes']})",
                f"controller state: {r['state_bytes']} bytes",
            ]
        )
    rows = [f"{r['fsm']} against python: {'identical' if r['identical'] else 'DIFFERENT'} "
            f"(the C state: {r['state_bytes']} bytes)"]  # fmt: skip
    for key, what in (("oracle_boards", "random oracle boards"), ("maps", "map files")):
        t = r[key]
        if t["boards"]:
            rows.append(f"{what}: {t['boards']} tours ({t['complete']} complete), {t['ticks']:,} ticks, "
                        f"{t['decisions']:,} decisions, {t['different']} different")  # fmt: skip
    p = r["random_pairs"]
    if p:
        rows.append(f"random pairs: {p['pairs']:,}, {p['same']:,} the same ({p['refused_by_both']:,} refused by both), "
                    f"{p['different']} different")  # fmt: skip
    for key in ("oracle_boards", "maps", "random_pairs"):
        if r[key] and r[key].get("first_difference"):
            rows.append(f"first difference ({key}): {r[key]['first_difference']}")
    return "\n".join(rows)
