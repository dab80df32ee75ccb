"""STC boards: a grid of sub-cells (side ``D``), cells of 2x2 sub-cells, obstacle cells with red lights.

Map files
---------
* **text**: one character per sub-cell, ``.`` free, ``#`` blocked, ``S`` the start sub-cell
  (free). Blank lines and lines starting with ``;`` are ignored. Exactly one ``S``.
* **PNG** (or any image OpenCV reads): one pixel = one sub-cell, dark (grey < 128) = blocked.
  This is the convention of PythonRobotics' coverage maps (white = free). An image carries no
  start, so the start is the lower-right sub-cell of the first free cell found scanning the cell
  rows top-down, left to right, unless the caller gives one.

Both dimensions must be even (a cell is 2x2 sub-cells). A cell is free iff all four of its
sub-cells are free; every other cell is an obstacle cell and carries a red light at its centre.
Cells beyond the board's edge read as blocked too: :meth:`Board.red_lights_m` adds a ring of red
lights one cell outside the border (``docs/explanation/stc-geometry.md``, "Parent, child and the
start cell").

Frames: row 0 is the map's top (north) row. World x is east along the columns, y north, with the
origin at the board's south-west corner, so sub-cell ``(i, j)`` has its centre at
``x = (j + 0.5) D``, ``y = H - (i + 0.5) D``.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from stcvision.errors import MapError
from stcvision.stc_geometry import DEFAULT_SUBCELL_M

__all__ = ["DEFAULT_SUBCELL_M", "Board"]

# DEFAULT_SUBCELL_M (re-exported here, the board's default sub-cell side) is defined once, in
# stcvision.stc_geometry, because the calibration profile's default needs it too and stcvision may not
# import the simulator.

_TEXT_CHARS = {".": False, "#": True, "S": False}
#: the most cells a random board may have (1000 x 1000): bounds its memory (a scene asking for
#: 2^70 cells failed deep in numpy, found by fuzzing)
MAX_RANDOM_CELLS = 1_000_000


def _check_even(shape: tuple[int, int], source: str) -> None:
    """Refuse a grid of odd rows or columns (a cell is 2x2 sub-cells)."""
    rows, cols = shape
    if rows % 2 or cols % 2:
        raise MapError(f"{source} is {rows}x{cols} sub-cells; expected even rows and columns (a cell is 2x2 sub-cells)")


@dataclass(frozen=True, eq=False)
class Board:
    """An STC board of sub-cells.

    Parameters
    ----------
    blocked : (rows, cols) bool
        ``True`` for blocked sub-cells; row 0 is north. ``rows`` and ``cols`` are even.
    start_subcell : (i, j)
        The sub-cell the robot starts in; its cell must be free.
    subcell_m : float
        Sub-cell side ``D`` in metres.

    Attributes
    ----------
    cell_free : (rows / 2, cols / 2) bool
        ``True`` for free cells (all four sub-cells free); read-only, like ``blocked``.

    Raises
    ------
    MapError
        When the grid is empty, not 2-D or of odd rows or columns, ``subcell_m`` is not
        positive, or the start sub-cell is off the board or in an obstacle cell.
    """

    blocked: np.ndarray
    start_subcell: tuple[int, int]
    subcell_m: float = DEFAULT_SUBCELL_M
    cell_free: np.ndarray = field(init=False, repr=False)

    def __post_init__(self) -> None:
        blocked = np.asarray(self.blocked)
        if blocked.ndim != 2 or blocked.size == 0:
            raise MapError(f"board must be a non-empty 2-D grid of sub-cells, got shape {blocked.shape}")
        _check_even(blocked.shape, "board")
        rows, cols = blocked.shape
        if not self.subcell_m > 0:
            raise MapError(f"subcell_m must be > 0 metres, got {self.subcell_m}")
        blocked = blocked.astype(bool, copy=True)
        blocked.setflags(write=False)
        object.__setattr__(self, "blocked", blocked)
        free = ~blocked.reshape(rows // 2, 2, cols // 2, 2).any(axis=(1, 3))
        free.setflags(write=False)
        object.__setattr__(self, "cell_free", free)
        i, j = (int(v) for v in self.start_subcell)
        if not (0 <= i < rows and 0 <= j < cols):
            raise MapError(f"start sub-cell ({i},{j}) is outside the {rows}x{cols} board")
        if not free[i // 2, j // 2]:
            raise MapError(f"start sub-cell ({i},{j}) lies in an obstacle cell; expected a free cell")
        object.__setattr__(self, "start_subcell", (i, j))

    # ------------------------------------------------------------------ constructors
    @classmethod
    def from_text(cls, text: str, *, subcell_m: float = DEFAULT_SUBCELL_M, source: str = "map") -> Board:
        """Parse a text map (``.`` free, ``#`` blocked, ``S`` start).

        One character per sub-cell; blank lines and lines starting with ``;`` are ignored.

        Parameters
        ----------
        text : str
            The map's text: a rectangle of even rows and columns, with exactly one ``S``.
        subcell_m : float
            Sub-cell side ``D`` in metres.
        source : str
            Names the map in error messages.

        Returns
        -------
        Board
            The board, starting in the ``S`` sub-cell.

        Raises
        ------
        MapError
            For an empty map, a line of another width, an unknown character, odd rows or
            columns, or not exactly one ``S``.
        """
        lines = [ln.rstrip("\r\n").rstrip() for ln in text.splitlines()]
        lines = [ln for ln in lines if ln and not ln.startswith(";")]
        if not lines:
            raise MapError(f"{source} is empty; expected rows of '.', '#' and one 'S'")
        width = len(lines[0])
        start = []
        grid = np.zeros((len(lines), width), bool)
        for i, ln in enumerate(lines):
            if len(ln) != width:
                raise MapError(
                    f"{source} line {i + 1} has {len(ln)} sub-cells, line 1 has {width}; expected a rectangle"
                )
            for j, ch in enumerate(ln):
                if ch not in _TEXT_CHARS:
                    raise MapError(
                        f"{source} line {i + 1} column {j + 1}: unknown character {ch!r}; expected '.', '#' or 'S'"
                    )
                grid[i, j] = _TEXT_CHARS[ch]
                if ch == "S":
                    start.append((i, j))
        _check_even(grid.shape, source)
        if len(start) != 1:
            what = "no start" if not start else f"{len(start)} starts"
            raise MapError(f"{source} has {what}; expected exactly one 'S' sub-cell")
        return cls(grid, start[0], subcell_m)

    @classmethod
    def from_image(cls, image: np.ndarray, *, subcell_m: float = DEFAULT_SUBCELL_M, start_subcell=None) -> Board:
        """Make a board from an image: one pixel = one sub-cell, dark (< 128) = blocked.

        Parameters
        ----------
        image : numpy.ndarray
            A grey or BGR uint8 image (1, 3 or 4 channels are averaged).
        subcell_m : float
            Sub-cell side ``D`` in metres.
        start_subcell : tuple of int, optional
            The start sub-cell; default the lower-right sub-cell of the first free cell found
            scanning the cell rows top-down, left to right.

        Returns
        -------
        Board
            The board.

        Raises
        ------
        MapError
            For an image of another shape, odd rows or columns, no free cell, or a start in an
            obstacle cell.
        """
        img = np.asarray(image)
        if img.ndim == 3 and img.shape[2] in (1, 3, 4):
            img = img.mean(axis=2)
        if img.ndim != 2:  # a 3-D array of 0 or 5 channels too (fuzzing: a 0-channel image read as all free)
            raise MapError(f"map image must be 2-D (grey) or 3-D with 1, 3 or 4 channels, got shape {img.shape}")
        blocked = img < 128
        if start_subcell is None:
            start_subcell = cls._default_start(blocked)
        return cls(blocked, start_subcell, subcell_m)

    @classmethod
    def from_occupancy(
        cls, free_px: np.ndarray, m_per_px: float, *, subcell_m: float = DEFAULT_SUBCELL_M, start_subcell=None,
        source: str = "map",
    ) -> Board:  # fmt: skip
        """Make a board from an occupancy grid of known resolution.

        A sub-cell is free iff every map pixel it overlaps is free, so the robot's footprint
        (``subcell_m``) fits wherever the board says free.

        Parameters
        ----------
        free_px : numpy.ndarray
            (H, W) bool, True where the map is free (row 0 the map's top).
        m_per_px : float
            The map's resolution, metres per pixel.
        subcell_m : float
            The board's sub-cell side, the robot's footprint.
        start_subcell : tuple of int, optional
            (row, column) of the start sub-cell; default: the first free cell's.
        source : str
            How a problem names the map.

        Returns
        -------
        Board
            The largest board of whole cells (2 x 2 sub-cells) that fits the map, its lower-left
            corner at the map's lower-left corner.

        Raises
        ------
        MapError
            A resolution that is not a positive number, or a map smaller than one cell.
        """
        free_px = np.asarray(free_px, bool)
        if not (isinstance(m_per_px, int | float) and np.isfinite(m_per_px) and m_per_px > 0):
            raise MapError(f"{source}: resolution {m_per_px!r} m per pixel; expected a positive number")
        h, w = free_px.shape
        rows = 2 * int(h * m_per_px / subcell_m / 2 + 1e-9)
        cols = 2 * int(w * m_per_px / subcell_m / 2 + 1e-9)
        if rows < 2 or cols < 2:
            raise MapError(
                f"{source} is {w * m_per_px:.2f} x {h * m_per_px:.2f} m (W x H), smaller than one cell of "
                f"{2 * subcell_m:.2f} m; expected a map at least a cell wide and high"
            )
        # blocked pixels counted over any rectangle in O(1): the integral image
        blocked = np.zeros((h + 1, w + 1), np.int64)
        blocked[1:, 1:] = np.cumsum(np.cumsum(~free_px, axis=0), axis=1)
        step = subcell_m / m_per_px  # pixels per sub-cell side
        x0 = np.floor(np.arange(cols) * step + 1e-9).astype(int)
        x1 = np.minimum(np.ceil((np.arange(cols) + 1) * step - 1e-9).astype(int), w)
        bottom = h - rows * step  # the board's top edge, in pixel rows (lower-left corners aligned)
        y0 = np.floor(bottom + np.arange(rows) * step + 1e-9).astype(int)
        y1 = np.minimum(np.ceil(bottom + (np.arange(rows) + 1) * step - 1e-9).astype(int), h)
        Y0, X0 = np.meshgrid(y0, x0, indexing="ij")
        Y1, X1 = np.meshgrid(y1, x1, indexing="ij")
        n_blocked = blocked[Y1, X1] - blocked[Y0, X1] - blocked[Y1, X0] + blocked[Y0, X0]
        sub_blocked = n_blocked > 0
        if start_subcell is None:
            start_subcell = cls._default_start(sub_blocked)
        return cls(sub_blocked, start_subcell, subcell_m)

    @classmethod
    def from_map_yaml(cls, path: str | Path, *, subcell_m: float = DEFAULT_SUBCELL_M, start_subcell=None) -> Board:
        """Make a board from a ROS ``map_server`` map.

        The map is its YAML (``image``, ``resolution``, ``origin``, ``negate``,
        ``occupied_thresh``, ``free_thresh``, optional ``mode``) and its image. A pixel's
        occupancy is ``(255 - v) / 255`` (``v / 255`` when ``negate``), its channels averaged;
        it is free below ``free_thresh``, and anything else (occupied, or unknown between the
        thresholds) is not: the robot does not drive where the map does not know. The board
        keeps the map's scale (:meth:`from_occupancy`); ``origin`` places the map in the lab's
        frame and does not change which sub-cells are free.

        Parameters
        ----------
        path : str or Path
            The map's YAML; its ``image`` is relative to the YAML's folder.
        subcell_m : float
            The board's sub-cell side, the robot's footprint.
        start_subcell : tuple of int, optional
            (row, column) of the start sub-cell; default: the first free cell's.

        Returns
        -------
        Board
            The board :meth:`from_occupancy` makes of the map at its resolution.

        Raises
        ------
        MapError
            A YAML that cannot be read or lacks a key, a value out of range, an image that
            cannot be read.
        """
        import yaml

        path = Path(path)
        try:
            meta = yaml.safe_load(path.read_text(encoding="utf-8"))
        except (OSError, UnicodeDecodeError, yaml.YAMLError) as exc:
            raise MapError(f"cannot read map YAML {path}: {str(exc).splitlines()[0]}") from None
        if not isinstance(meta, dict):
            raise MapError(f"map YAML {path} is not a mapping; expected map_server's keys (image, resolution, ...)")
        missing = [k for k in ("image", "resolution", "occupied_thresh", "free_thresh") if k not in meta]
        if missing:
            raise MapError(f"map YAML {path} has no {missing[0]!r}; expected map_server's keys")

        def number(key, lo, hi):
            v = meta[key]
            if isinstance(v, bool) or not isinstance(v, int | float) or not (lo <= v <= hi):
                raise MapError(f"map YAML {path}: {key} is {v!r}; expected a number in [{lo}, {hi}]")
            return float(v)

        res = number("resolution", 1e-6, 1e3)
        occ, free = number("occupied_thresh", 0, 1), number("free_thresh", 0, 1)
        if free > occ:
            raise MapError(f"map YAML {path}: free_thresh {free} is above occupied_thresh {occ}")
        negate = meta.get("negate", 0)
        if negate not in (0, 1, True, False):
            raise MapError(f"map YAML {path}: negate is {negate!r}; expected 0 or 1")
        if meta.get("mode", "trinary") not in ("trinary", "scale", "raw"):
            raise MapError(f"map YAML {path}: mode {meta['mode']!r}; expected trinary, scale or raw")
        if not isinstance(meta["image"], str) or not meta["image"]:
            raise MapError(f"map YAML {path}: image is {meta['image']!r}; expected the map image's file name")
        from stcvision.fileio import read_image

        img_path = (path.parent / meta["image"]) if not Path(meta["image"]).is_absolute() else Path(meta["image"])
        try:
            img = read_image(img_path, color=False, what="map image")
        except Exception as exc:  # BadInputError -> MapError with the same message
            raise MapError(str(exc)) from None
        v = img.astype(np.float64) / float(np.iinfo(img.dtype).max)
        occupancy = v if negate else 1.0 - v
        return cls.from_occupancy(
            occupancy < free, res, subcell_m=subcell_m, start_subcell=start_subcell, source=f"map {path}"
        )

    @classmethod
    def from_file(
        cls,
        path: str | Path,
        *,
        subcell_m: float = DEFAULT_SUBCELL_M,
        start_subcell=None,
        m_per_px: float | None = None,
    ) -> Board:
        """Load a ``.txt`` map, a ROS ``map_server`` ``.yaml`` map, or an image map.

        An image map (``.png``, ``.bmp``...) is one pixel per sub-cell, or, given ``m_per_px``
        (its resolution), resampled to sub-cells of ``subcell_m`` (:meth:`from_occupancy`).

        Parameters
        ----------
        path : str or Path
            The map file: ``.txt``, ``.map`` or no suffix for a text map, ``.yaml`` or ``.yml``
            for a ``map_server`` map, else an image.
        subcell_m : float
            Sub-cell side ``D`` in metres.
        start_subcell : tuple of int, optional
            The start sub-cell, instead of the text map's ``S`` or the image map's default.
        m_per_px : float, optional
            An image map's resolution (metres per pixel); not for text or YAML maps.

        Returns
        -------
        Board
            The board.

        Raises
        ------
        MapError
            A missing file or folder, a map that cannot be read or parsed, a resolution given
            where the map has its own or has none.
        """
        path = Path(path)
        if path.is_dir():
            raise MapError(f"map {path} is a folder; expected a .txt, .yaml or image map file")
        if not path.is_file():
            raise MapError(f"map file {path} does not exist")
        if path.suffix.lower() in (".yaml", ".yml"):
            if m_per_px is not None:
                raise MapError(f"map {path} gives its own resolution; drop --resolution")
            return cls.from_map_yaml(path, subcell_m=subcell_m, start_subcell=start_subcell)
        if m_per_px is not None and path.suffix.lower() in (".txt", ".map", ""):
            raise MapError(f"map {path} is a text map of sub-cells; --resolution is for image maps")
        if path.suffix.lower() in (".txt", ".map", ""):
            try:
                text = path.read_text(encoding="utf-8")
            except (OSError, UnicodeDecodeError) as exc:
                raise MapError(f"cannot read text map {path}: {exc}") from None
            board = cls.from_text(text, subcell_m=subcell_m, source=f"map {path}")
            if start_subcell is not None:
                board = cls(board.blocked, start_subcell, subcell_m)
            return board
        from stcvision.fileio import read_image

        try:
            img = read_image(path, color=False, what="map image")
        except Exception as exc:  # BadInputError -> MapError with the same message
            raise MapError(str(exc)) from None
        if m_per_px is not None:
            return cls.from_occupancy(
                img >= 128, m_per_px, subcell_m=subcell_m, start_subcell=start_subcell, source=f"map {path}"
            )
        return cls.from_image(img, subcell_m=subcell_m, start_subcell=start_subcell)

    @classmethod
    def random(
        cls,
        cells_shape: tuple[int, int],
        *,
        obstacle_fraction: float = 0.1,
        rng: np.random.Generator,
        subcell_m: float = DEFAULT_SUBCELL_M,
    ) -> Board:
        """Make a random board of ``cells_shape`` cells with about ``obstacle_fraction`` obstacle cells.

        The start is the lower-right sub-cell of the first free cell (rows top-down); at least
        one cell is always free.

        Parameters
        ----------
        cells_shape : tuple of int
            (rows, columns) of cells, at most :data:`MAX_RANDOM_CELLS` cells in all.
        obstacle_fraction : float
            The chance of each cell being an obstacle cell, in [0, 1).
        rng : numpy.random.Generator
            Draws the obstacle cells.
        subcell_m : float
            Sub-cell side ``D`` in metres.

        Returns
        -------
        Board
            The board.

        Raises
        ------
        MapError
            For fewer than 1x1 cells, too many cells, or a fraction outside [0, 1).
        """
        cr, cc = (int(v) for v in cells_shape)
        if cr < 1 or cc < 1:
            raise MapError(f"board must have at least 1x1 cells, got {cr}x{cc}")
        if cr * cc > MAX_RANDOM_CELLS:
            raise MapError(f"board of {cr}x{cc} cells is too large; expected at most {MAX_RANDOM_CELLS:,} cells")
        if not 0.0 <= obstacle_fraction < 1.0:
            raise MapError(f"obstacle_fraction must be in [0, 1), got {obstacle_fraction}")
        cells = rng.random((cr, cc)) < obstacle_fraction
        if cells.all():
            cells[rng.integers(cr), rng.integers(cc)] = False
        blocked = np.repeat(np.repeat(cells, 2, axis=0), 2, axis=1)
        return cls(blocked, cls._default_start(blocked), subcell_m)

    @staticmethod
    def _default_start(blocked: np.ndarray) -> tuple[int, int]:
        """Return the lower-right sub-cell of the first free cell, scanning the cell rows top-down."""
        _check_even(blocked.shape, "board")
        rows, cols = blocked.shape
        free = ~blocked.reshape(rows // 2, 2, cols // 2, 2).any(axis=(1, 3))
        idx = np.argwhere(free)
        if len(idx) == 0:
            raise MapError("board has no free cell (a cell is free iff its 4 sub-cells are free)")
        ci, cj = idx[0]
        return (2 * int(ci) + 1, 2 * int(cj) + 1)

    # ------------------------------------------------------------------ geometry
    @property
    def shape_subcells(self) -> tuple[int, int]:
        """(rows, columns) of sub-cells."""
        return self.blocked.shape

    @property
    def shape_cells(self) -> tuple[int, int]:
        """(rows, columns) of cells."""
        return self.cell_free.shape

    @property
    def cell_m(self) -> float:
        """Cell side ``2 D`` in metres."""
        return 2.0 * self.subcell_m

    @property
    def size_m(self) -> tuple[float, float]:
        """(width, height) of the board in metres."""
        rows, cols = self.blocked.shape
        return (cols * self.subcell_m, rows * self.subcell_m)

    @property
    def start_cell(self) -> tuple[int, int]:
        """(row, column) of the cell holding the start sub-cell."""
        return (self.start_subcell[0] // 2, self.start_subcell[1] // 2)

    def subcell_center_m(self, i: int, j: int) -> np.ndarray:
        """Return the world (x, y) of the centre of sub-cell (row ``i``, column ``j``)."""
        h = self.blocked.shape[0] * self.subcell_m
        return np.array([(j + 0.5) * self.subcell_m, h - (i + 0.5) * self.subcell_m])

    def cell_center_m(self, ci: int, cj: int) -> np.ndarray:
        """Return the world (x, y) of the centre of cell (row ``ci``, column ``cj``); may lie off the board."""
        h = self.blocked.shape[0] * self.subcell_m
        return np.array([(cj + 0.5) * self.cell_m, h - (ci + 0.5) * self.cell_m])

    def subcell_at(self, xy_m) -> tuple[int, int]:
        """Return (row, column) of the sub-cell containing world point ``xy_m`` (may be off the board)."""
        x, y = float(xy_m[0]), float(xy_m[1])
        h = self.blocked.shape[0] * self.subcell_m
        return (int(np.floor((h - y) / self.subcell_m)), int(np.floor(x / self.subcell_m)))

    def is_cell_free(self, ci: int, cj: int) -> bool:
        """Say whether a cell is free: ``True`` for a free cell on the board; cells off it read as blocked."""
        cr, cc = self.cell_free.shape
        return bool(0 <= ci < cr and 0 <= cj < cc and self.cell_free[ci, cj])

    def red_lights_m(self) -> np.ndarray:
        """Return the (N, 2) world positions of the red lights.

        Every obstacle cell's centre plus a ring of virtual obstacle cells one cell outside the
        border.
        """
        cr, cc = self.cell_free.shape
        cells = [tuple(c) for c in np.argwhere(~self.cell_free)]
        cells += [(-1, j) for j in range(-1, cc + 1)] + [(cr, j) for j in range(-1, cc + 1)]
        cells += [(i, -1) for i in range(cr)] + [(i, cc) for i in range(cr)]
        return np.array([self.cell_center_m(i, j) for i, j in cells], dtype=float).reshape(-1, 2)

    def reachable_cells(self, start_cell: tuple[int, int] | None = None) -> np.ndarray:
        """Return the free cells 4-connected to ``start_cell``, as a (cells_rows, cells_cols) bool array.

        ``start_cell`` defaults to the start sub-cell's cell.
        """
        start = self.start_cell if start_cell is None else tuple(start_cell)
        cr, cc = self.cell_free.shape
        seen = np.zeros((cr, cc), bool)
        if not self.is_cell_free(*start):
            return seen
        seen[start] = True
        todo = deque([start])
        while todo:
            i, j = todo.popleft()
            for di, dj in ((1, 0), (-1, 0), (0, 1), (0, -1)):
                a, b = i + di, j + dj
                if 0 <= a < cr and 0 <= b < cc and self.cell_free[a, b] and not seen[a, b]:
                    seen[a, b] = True
                    todo.append((a, b))
        return seen

    def to_text(self) -> str:
        """Return the board as a text map (round-trips through :meth:`from_text`)."""
        chars = np.where(self.blocked, "#", ".")
        chars[self.start_subcell] = "S"
        return "\n".join("".join(r) for r in chars) + "\n"
