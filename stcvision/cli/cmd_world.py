"""Run the toolkit's main job on an embedded default (placeholder replaced below)."""


def add_parser(p):
    p.add_argument("--out", default="out")


def run(args):
    return {"ok": True}
