"""The lines an STC tour marks in a cell read from outside it (a neighbour, the cell ahead), and
whether a frame's dots show one of its rows: against the geometry the simulator lays rows with."""

from __future__ import annotations

import numpy as np
import pytest

from stcvision.controllers.stc.cellfit import shows_row, shows_tour_row, tour_lines
from stcvision.observation import MARK_INSET
from stcvision.sim_camera.phosphor import LED_OFFSETS_M
from stcvision.stc_geometry import DEFAULT_SUBCELL_M, DIRECTIONS, SUBCELLS


def _row(m: int, edge: int, *, shift=(0.0, 0.0), centre=(0.0, 0.0)) -> np.ndarray:
    """The four dots (cell units) of a row on edge ``edge`` of sub-cell ``m`` of the cell centred at
    ``centre``, laid as the robot lays them: ``MARK_INSET`` inside the edge, the LEDs' spacing along it."""
    e = np.asarray(DIRECTIONS[edge], float)
    along = np.array([-e[1], e[0]])
    c = np.asarray(centre, float) + 0.5 * np.asarray(SUBCELLS[m], float) + (0.5 - MARK_INSET) * e
    return c + np.outer(np.asarray(LED_OFFSETS_M) / DEFAULT_SUBCELL_M, along) + np.asarray(shift)


def test_a_tour_marks_twelve_lines_in_a_cell_whatever_its_entry_frame():
    """Sub-cell m is left towards m + 1 (a row on its edge m + 3) or out towards m (edge m + 2);
    the start mark lies on edge m: the eight exterior edges and four of the eight interior ones."""
    lines = tour_lines()
    assert len(lines) == 12
    exterior = sum(abs(c) > 0.5 for _, c, _, _ in lines)
    assert exterior == 8


@pytest.mark.parametrize("centre", [(2.0, 0.0), (0.0, 2.0), (-2.0, 0.0), (0.0, -2.0), (0.0, 1.0)])
def test_every_row_a_tour_lays_in_a_cell_is_shown_and_no_other(centre):
    """Every row the tour lays, seen whole or with three of its four dots, and up to 0.9 cm off
    its line (the robot's own offset), shows; a row on an interior edge the tour never marks, a
    row of the next cell read 2.4 cm across the shared edge, two dots or a scatter do not."""
    lit = np.ones(4, bool)
    for m in range(4):
        for edge, tour in (((m + 2) % 4, True), ((m + 3) % 4, True), (m, True), ((m + 1) % 4, False)):
            row = _row(m, edge, centre=centre)
            assert shows_tour_row(row, lit, centre) is tour, (m, edge)
            if tour:
                assert shows_tour_row(row[1:], lit[1:], centre)  # three of four
                assert shows_tour_row(row + 0.055 * np.asarray(DIRECTIONS[edge]), lit, centre)
                assert not shows_tour_row(row[:2], lit[:2], centre)  # two dots are no row
                assert not shows_tour_row(row, np.array([True, True, False, False]), centre)
    scatter = np.asarray(centre) + np.random.default_rng(0).uniform(-0.9, 0.9, (6, 2))
    assert not shows_tour_row(scatter, np.ones(6, bool), centre)


def test_a_row_of_the_readers_own_cell_read_across_the_edge_is_no_neighbours_row():
    """The reader's row on its cell's right edge (sub-cell 0, edge 0), read with the robot's offset
    2.4 cm off (0.15 of a sub-cell), falls in the right neighbour's region 0.1 from the nearest
    of that cell's lines: it is not taken for the neighbour's mark. Read 4 cm off (0.25), it
    would lie on the neighbour's line itself: no reading of the floor can tell that apart, which
    is why the robot recentres beyond 2.5 cm (``RECENTRE_M``)."""
    lit = np.ones(4, bool)
    own = _row(0, 0)
    assert not shows_tour_row(own, lit, (2.0, 0.0))
    assert not shows_tour_row(own + (0.15, 0.0), lit, (2.0, 0.0))
    assert shows_tour_row(own + (0.25, 0.0), lit, (2.0, 0.0))


def test_a_row_of_the_leds_shows_wherever_it_lies_and_scattered_dots_do_not():
    """The look's test: a row of the robot's LEDs inside the cell ahead, whole or three of its
    four dots, on a tour line or 4 cm off it (a look reads where the robot believes it stands);
    two dots, a scatter, or a row outside the cell show none."""
    centre = (0.0, 1.0)
    lit = np.ones(4, bool)
    for m, edge in ((1, 0), (2, 1), (0, 2), (3, 3)):
        row = _row(m, edge, centre=centre)
        assert shows_row(row, lit, centre) and shows_row(row[1:], lit[1:], centre)
        assert shows_row(row + 0.25 * np.asarray(DIRECTIONS[(edge + 1) % 4], float), lit, centre)
        assert not shows_row(row[:2], lit[:2], centre)
    scatter = np.array([[0.3, 1.2], [0.45, 1.5], [-0.2, 1.3], [0.1, 1.75]])
    assert not shows_row(scatter, np.ones(4, bool), centre)
    assert not shows_row(_row(1, 0, centre=(0.0, 3.0)), lit, centre)  # the cell beyond
