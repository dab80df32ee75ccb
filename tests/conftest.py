"""Shared fixtures. Paths to the peer data other projects made (used as users would).

The peer files are vendored in ``datasets/peer_data/`` (sources and licences in its README), so a
clone anywhere runs every test: a missing file is a failure, never a skip."""

import signal
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PEER = ROOT / "datasets" / "peer_data"


def pytest_configure(config):
    """A test session started in the background of a non-interactive shell (a CI script's
    ``make test &``, ``nohup``) inherits SIGINT ignored, and so would every command the tests
    start: Python then leaves Ctrl-C ignored too, and the tests that check a command stops on
    Ctrl-C would fail for the shell's reason, not the command's. A handler here (it becomes the
    default action across ``exec``) gives the commands the Ctrl-C a user's terminal gives them."""
    if signal.getsignal(signal.SIGINT) is signal.SIG_IGN:
        signal.signal(signal.SIGINT, signal.default_int_handler)


def pytest_collection_modifyitems(config, items):
    """The modules that hold slow tests first, each module whole and in its own order (a module's
    fixtures are made once), the rest after. pytest-xdist hands each worker a run of the list and
    lets an idle one take from the end of another's: with the slow ones first, the tests left at
    the end are short ones and the two workers end within seconds of each other (a tour or a
    documentation page last kept one worker busy alone for up to half a minute)."""

    def module(item):
        return getattr(item, "fspath", None)

    slow = {module(item) for item in items if item.get_closest_marker("slow")}
    items.sort(key=lambda item: module(item) not in slow)


SMOKE_RECIPE = ROOT / "datasets" / "recipes" / "smoke.json"


@pytest.fixture(scope="session")
def smoke(tmp_path_factory):
    """The tiny shipped 'smoke' recipe generated once per session (read-only: copy it before changing it)."""
    from stcvision.cli import main

    d = tmp_path_factory.mktemp("smoke") / "D"
    assert main(["dataset", "generate", str(SMOKE_RECIPE), "--out", str(d), "--workers", "1"]) == 0
    return d


@pytest.fixture(scope="session")
def peer_data() -> Path:
    assert PEER.is_dir(), f"the vendored peer data is missing: {PEER}"
    return PEER


@pytest.fixture(scope="session")
def default_camera():
    from stcvision.sim_camera.camera import SyntheticCamera

    return SyntheticCamera()


@pytest.fixture
def cli(capsys):
    """Run ``stcvision ARGV...`` in-process; returns (exit code, stdout, stderr)."""
    from stcvision.cli import main

    def run(*argv) -> tuple[int, str, str]:
        capsys.readouterr()
        code = main([str(a) for a in argv])
        out = capsys.readouterr()
        return code, out.out, out.err

    return run


class RrdContents:
    """A rerun recording read back with rerun's own reader (``rerun.chunk.RrdReader``): what
    its data store and its blueprint store hold."""

    def __init__(self, path) -> None:
        from rerun.chunk import RrdReader

        self.reader = RrdReader(str(path))

    def _rows(self, store=None):
        for ch in self.reader.stream(store=store):
            rb = ch.to_record_batch()
            yield ch.entity_path, {n: rb.column(n).to_pylist() for n in rb.schema.names if "RowId" not in n}

    def times(self, entity: str, timeline: str) -> list:
        """The ``timeline`` values at which ``entity`` was logged, sorted."""
        return sorted(v for e, cols in self._rows() if e == entity for v in cols.get(timeline, []))

    def column(self, entity: str, component: str) -> list:
        """Every value ``entity`` logged for ``component`` (e.g. ``TextLog:text``), in the order stored."""
        return [v for e, cols in self._rows() if e == entity for v in cols.get(component, [])]

    def properties(self) -> dict:
        """The recording's properties (name, and what the toolkit sent), the last value of each."""
        out = {}
        for e, cols in self._rows():
            if e.startswith("/__properties"):
                for k, v in cols.items():
                    out[f"{e}:{k}"] = v[-1]
        return out

    def views(self) -> list[tuple[str, str, str]]:
        """The default blueprint's views: (kind, name, origin) each."""
        (bp,) = self.reader.blueprints()
        views = [cols for e, cols in self._rows(bp) if "ViewBlueprint:class_identifier" in cols]
        return sorted(
            (v["ViewBlueprint:class_identifier"][0][0], v["ViewBlueprint:display_name"][0][0],
             v["ViewBlueprint:space_origin"][0][0])
            for v in views
        )  # fmt: skip

    def time_panel(self) -> dict:
        """The default blueprint's time panel: its state and its timeline."""
        (bp,) = self.reader.blueprints()
        return {k.split(":")[1]: v[0][0] for e, cols in self._rows(bp) if e == "/time_panel"
                for k, v in cols.items() if k.startswith("TimePanelBlueprint")}  # fmt: skip


@pytest.fixture
def rrd_contents():
    """``rrd_contents(path)``: a recording read back (:class:`RrdContents`)."""
    return RrdContents
