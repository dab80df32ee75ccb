"""A reading's absences are only worth what its frames could have seen. The claim
distances come from the STC geometry; frames are added until each claim is covered, or the
robot stops before deciding."""

import dataclasses

import numpy as np
import pytest

from stcvision.controllers.stc.claims import (
    OutOfSight,
    ahead_claims,
    decision_claims,
    distance_m,
    landing_claims,
    read_until_sure,
    return_misread,
)
from stcvision.controllers.stc.fsm import REENTRY_BOXES, NeighbourObs, StcObservation
from stcvision.controllers.stc.loop import CoverConfig, run_cover
from stcvision.sim_camera.board import Board
from stcvision.sim_camera.robot import LEGO_STC_ROBOT


def test_claim_distances_follow_the_geometry():
    """The deciding dot of each claim, 0.16 m sub-cells, no margin (hand-computed from the
    entry frame: robot at sub-cell 0's centre, rows 2 cm inside their edge, dots at +-1.5 and
    +-4.5 cm along it; the second-nearest dot for a box, the third for a landing sub-cell)."""
    kinds = ("box 1", "box 2", "box 5", "start mark 2", "cell ahead", "landing ahead")
    d = {k: distance_m(k, 0.16, 0.0) for k in kinds}
    assert d["box 5"] == pytest.approx(0.101, abs=1e-3)  # sub-cell 1's bottom edge, beside the robot
    assert d["box 1"] == pytest.approx(0.157, abs=1e-3)
    assert d["box 2"] == pytest.approx(0.263, abs=1e-3) == d["start mark 2"]  # the far corner
    assert d["cell ahead"] == pytest.approx(0.407, abs=1e-3)  # the far sub-cell's far edge
    assert d["landing ahead"] == pytest.approx(0.225, abs=1e-3)
    assert distance_m("box 2", 0.16, 0.02) == pytest.approx(d["box 2"] + 0.02)


def _obs(boxes, start=None):
    n = (NeighbourObs(False, False),) * 4
    return StcObservation(tuple(bool(b) for b in boxes), n, start)


def test_what_a_decision_rules_out():
    kw = dict(subcell_m=0.16, margin_m=0.0)
    claims = decision_claims(_obs((0, 1, 0, 1, 0)), fresh=False, at_start=False, **kw)
    assert [c.what for c in claims] == [
        "box 1 unlit", "box 3 unlit", "box 5 unlit",
        "no start mark in sub-cell 1", "no start mark in sub-cell 2", "no start mark in sub-cell 3",
    ]  # fmt: skip
    assert not decision_claims(_obs((0,) * 5), fresh=True, at_start=False, **kw)  # the look ruled them out
    seen_start = decision_claims(_obs((1, 1, 0, 1, 1), start=2), fresh=False, at_start=False, **kw)
    assert [c.what for c in seen_start] == ["box 3 unlit"]
    assert ahead_claims(True, **kw) == [] and landing_claims(True, **kw) == []  # what is seen needs no proof
    assert ahead_claims(False, **kw)[0].rho_m > landing_claims(False, **kw)[0].rho_m


class _Ladder:
    """A camera of three rungs whose horizon falls with the distance: 100 / 1,000 / 10,000 s at
    0.1 m, halving every 0.1 m."""

    ladder = (0, 1, 2)

    def horizon(self, k, rho_m):
        return 10.0 ** (k + 2) * 0.5 ** ((rho_m - 0.1) / 0.1)

    def rung_for(self, t_s, rho_m):
        return next((k for k in self.ladder if self.horizon(k, rho_m) >= t_s), None)


class _Claim:
    def __init__(self, what, rho_m):
        self.what, self.rho_m = what, rho_m


def _reader(seen_by):
    """read(k, t): the reading is the set of marks rung k sees; each frame takes 10 s."""
    taken = []

    def read(k, t):
        taken.append((k, t))
        return frozenset(seen_by.get(k, ())), 10.0

    return read, taken


def test_frames_are_added_until_every_absence_is_covered():
    cam = _Ladder()
    claims = lambda seen: [] if "far" in seen else [_Claim("no far mark", 0.3)]  # noqa: E731
    # at t = 50 s the short frame covers 0.3 m (25 s)? no: 100 * 0.25 = 25 s < 50 s -> rung 1 (250 s)
    read, taken = _reader({})
    reading, dt, frames = read_until_sure(cam, 50.0, read, frozenset.union, claims)
    assert frames == taken == [(0, 50.0), (1, 60.0)] and dt == 20.0
    # a mark the short frame already sees needs no longer frame
    read, taken = _reader({0: {"far"}})
    assert read_until_sure(cam, 50.0, read, frozenset.union, claims)[2] == [(0, 50.0)]
    # a mark only the long frame sees ends the claim there
    read, taken = _reader({2: {"far"}})
    reading, _, frames = read_until_sure(cam, 2000.0, read, frozenset.union, claims)
    assert [k for k, _ in frames] == [0, 2] and "far" in reading
    # past the longest frame's horizon at that distance (2,500 s): stop, saying what and where
    read, taken = _reader({})
    with pytest.raises(OutOfSight, match=r"no far mark \(0\.30 m away\).*3010 s old.*2500 s there"):
        read_until_sure(cam, 3000.0, read, frozenset.union, claims)
    # not strict: the longest frame, once, and the reading kept
    read, taken = _reader({})
    assert [k for k, _ in read_until_sure(cam, 3000.0, read, frozenset.union, claims, strict=False)[2]] == [0, 2]


@pytest.mark.parametrize("perception", ["ideal", "camera"])
def test_a_robot_past_its_camera_stops_before_deciding(perception):
    """A robot that waits 10 minutes before every reading: on a 5x5 board its clock soon passes
    what the webcam's longest frame (64 x 30 s) sees 0.43 m away, so it stops "out of sight" at
    a look, saying what it could not rule out -- having covered nothing twice and decided
    nothing wrong."""
    robot = dataclasses.replace(LEGO_STC_ROBOT, settle_s=600.0, fade_per_h=0.0)  # (no flat battery)
    board = Board.random((5, 5), obstacle_fraction=0.1, rng=np.random.default_rng(7))
    r = run_cover(board, CoverConfig(perception=perception, exposure="auto", seed=3, robot=robot))
    assert r["abort_reason"].startswith("out of sight: no mark in the cell ahead (0.43 m away)"), r
    assert not r["complete"] and r["subcells_covered"] < r["subcells_reachable"]
    assert r["subcells_covered_more_than_once"] == 0 and r["decision_errors"] == 0 and r["look_errors"] == 0


def test_a_return_reads_box_4_and_one_of_the_reentry_sets():
    """Of the 32 lit-box sets, a return from a child accepts exactly the seven the oracle shows
    on re-entry (tests/controllers/stc/test_oracle.py); any other says which boxes it read."""
    for bits in range(32):
        lit = tuple(b for b in range(1, 6) if bits >> (b - 1) & 1)
        why = return_misread(_obs([b in lit for b in range(1, 6)]))
        assert (why is None) == (lit in REENTRY_BOXES), lit
        if why is not None:
            assert why.startswith("misread: boxes {" + ",".join(map(str, lit)) + "} lit in a cell re-entered")
    assert all(4 in s for s in REENTRY_BOXES)


def _blind_to_box_4(up_to_rung: int):
    """A perception hook: every decision frame at rungs <= ``up_to_rung`` misses box 4 (a mark
    missed within the frame's reach, as the pipeline's red test once did on long webcam frames)."""

    def hook(see):
        decide_frames = see.cam.decision

        def decision(t_s, read, fresh, at_start, start_cell=True):
            def blind(k, t):
                obs, dt = read(k, t)
                if k <= up_to_rung:
                    obs = dataclasses.replace(obs, boxes=(*obs.boxes[:3], False, obs.boxes[4]))
                return obs, dt

            return decide_frames(t_s, blind, fresh, at_start, start_cell)

        see.cam.decision = decision

    return hook


def test_a_return_missing_box_4_is_read_again_then_stops_before_deciding():
    """The physics-limited camera made blind to box 4: with the return check the robot reads a
    return again with a longer frame and, blind there too, stops ("misread") at its first
    return with nothing covered twice and no wrong decision; without the check it decides on
    the misreading. Blind only in the short and the 2 s frame, the longer frame mends the
    reading and the tour completes."""
    board = Board.random((4, 4), obstacle_fraction=0.1, rng=np.random.default_rng(2))
    cfg = CoverConfig(perception="ideal", exposure="auto", seed=1)
    r = run_cover(board, cfg, perception_hook=_blind_to_box_4(99))
    assert r["abort_reason"].startswith("misread: boxes {"), r["abort_reason"]
    assert "also with a" in r["abort_reason"] and "(at sub-cell" in r["abort_reason"]
    assert r["subcells_covered_more_than_once"] == 0 and r["decision_errors"] == 0
    unchecked = run_cover(board, dataclasses.replace(cfg, check_returns=False), perception_hook=_blind_to_box_4(99))
    assert unchecked["decision_errors"] > 0 and not unchecked["complete"]
    mended = run_cover(board, cfg, perception_hook=_blind_to_box_4(1))
    assert mended["complete"], mended["abort_reason"]
    assert mended["long_exposures"] > run_cover(board, cfg)["long_exposures"]  # the re-reads


def test_frames_sized_by_their_own_noise_see_less_far_on_the_webcam():
    """A stack arrives digitised once, against a dark frame digitised too: on the webcam's 8-bit
    frames 32 x 30 s are worth ~12 frames (noise 0.52 DN by the camera's figures, measured 0.54
    in a run; the idealised noise over sqrt(32) says 0.32), a 16-bit cooled camera's ~0.85 of
    them. Sized so, the webcam's longest frame sees a mark 0.45 m away about half as long."""
    from stcvision.controllers.stc.frames import Exposures, IdealCamera, RobotCamera
    from stcvision.sim_camera.hardware import load_camera

    web = Exposures(CoverConfig(exposure="auto"))
    k = next(i for i, (e, _, n) in enumerate(web.ladder) if (e, n) == (30.0, 32))
    assert web.stack_equivalent(k) == pytest.approx(12.3, abs=0.3)
    cooled = Exposures(CoverConfig(exposure="auto", camera=load_camera("cooled")))
    assert 0.8 < cooled.stack_equivalent(k) / cooled.stack(k) < 0.9
    assert RobotCamera.frame_noise and not IdealCamera.frame_noise  # (the physics-limited camera stays ideal)
    honest = Exposures(CoverConfig(exposure="auto", size_by_frame_noise=True))
    honest.frame_noise = True
    last = len(web.ladder) - 1
    assert 0.45 < honest.horizon(last, 0.45) / web.horizon(last, 0.45) < 0.6


def test_an_unlit_box_at_a_return_near_its_frames_reach_is_read_with_the_next_longer_frame():
    """At a return the claims size the frames for each dot at ``sizing_snr``; an unlit box whose
    frames do not also reach the clock at the stricter ``return_snr`` is read again with the next
    longer rung, once; where they do, or in a fresh cell (nothing to miss), no frame is added."""
    from stcvision.controllers.stc.claims import distance_m
    from stcvision.controllers.stc.frames import Exposures
    from stcvision.sim_camera.hardware import load_camera

    cam = Exposures(CoverConfig(exposure="auto", camera=load_camera("cooled")))
    rho = distance_m("box 2", cam.subcell_m, cam.cfg.position_margin_m)  # the farthest box
    k = 3
    sized, strict = cam.horizon(k, rho), cam.horizon(k, rho, cam.cfg.return_snr)
    assert strict < sized  # each dot at 2 sigma above the threshold, not 1: a shorter reach
    clock = 0.5 * (sized + strict)  # rung 3's sizing horizon covers box 2, its stricter one does not
    taken: list[int] = []

    def read(k, t):
        taken.append(k)
        return StcObservation(boxes=lit, neighbours=(NeighbourObs(False, False),) * 4, start_mark=None), 1.0

    def frames(t_s, fresh):
        taken.clear()
        cam.decision(t_s, read, fresh=fresh, at_start=False)
        return list(taken)

    lit = (False, False, False, True, False)  # {4}: a return's set, box 2 unlit

    sized_only = [j for j, _ in cam.sure(clock, read, lambda a, b: a, cam.decision_claims(False, False))[2]]
    assert sized_only[-1] >= k
    before = cam.reread_old
    assert frames(clock, False) == [*sized_only, sized_only[-1] + 1] and cam.reread_old == before + 1
    lit = (False,) * 5
    assert frames(clock, True) == [0]  # a fresh cell, read empty: nothing to miss
    lit = (False, False, False, True, False)
    assert frames(1.0, False) == [0] and cam.reread_old == before + 1  # the short frame reaches 1 s at any SNR


def test_a_box_a_short_frame_reads_lit_and_a_longer_one_unlit_is_read_again():
    """At one pose a longer frame sees every mark a shorter one can. A box only a shorter frame
    read lit is read once more at that frame's rung and taken from it: a row of noise (not there
    again) is dropped, a mark the longer frame missed (there again) is kept. A box every frame
    agrees on, or one only the longer frame reads lit, takes no extra frame."""
    from stcvision.controllers.stc.frames import Exposures
    from stcvision.sim_camera.hardware import load_camera

    cam = Exposures(CoverConfig(exposure="auto", camera=load_camera("cooled")))
    clock = cam.horizon(0, distance_m("box 2", cam.subcell_m, cam.cfg.position_margin_m)) * 1.5  # needs rung 1
    none = (NeighbourObs(False, False),) * 4

    def decide(per_frame):
        taken: list[int] = []

        def read(k, t):
            boxes = per_frame(k, len(taken))
            taken.append(k)
            return StcObservation(boxes=boxes, neighbours=none, start_mark=None), 1.0

        obs, _ = cam.decision(clock, read, fresh=False, at_start=False)
        return obs.boxes, taken

    four, three_four = (False, False, False, True, False), (False, False, True, True, False)
    before = cam.disputed
    # the short frame's row of noise at box 3: not in the 2 s frame, nor in the short frame again
    boxes, taken = decide(lambda k, i: three_four if i == 0 else four)
    assert boxes == four and taken[-1] == 0 and len(taken) == 3 and cam.disputed == before + 1
    # a mark the longer frame missed shows again in the short frame: kept
    boxes, taken = decide(lambda k, i: four if (k > 0 and i == 1) else three_four)
    assert boxes == three_four and cam.disputed == before + 2
    # only the longer frame sees box 3 (an older mark): nothing disputed, no extra frame
    boxes, taken = decide(lambda k, i: three_four if k > 0 else four)
    assert boxes == three_four and len(taken) == 2 and cam.disputed == before + 2
