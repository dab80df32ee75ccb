"""How much older marks the faint-row search reads: ``python docs/measurements/row_gain.py EXPOSURE_S GAIN AGES``.

Renders 20 random STC entry situations per age (every mark that age, ``cell_scene`` with box
probability 0.5 and neighbour-mark probability 0.6, seed 5) at the given exposure and gain,
with a matching dark frame, and counts the marked boxes read lit with the full row search,
with its free search only (``RowParams(anchored=False)``) and without it
(``RowParams(enabled=False)``), the unmarked boxes read lit, and the neighbours' marks read.
Example: ``python docs/measurements/row_gain.py 8 4 1500,2500,3500,5000,7000``.
"""

import sys

import numpy as np

from stcvision.calibration.profiles import default_profile
from stcvision.pipeline import Pipeline, PipelineParams
from stcvision.sim_camera.camera import SyntheticCamera
from stcvision.sim_camera.scenarios import cell_scene
from stcvision.stages import RowParams

cam = SyntheticCamera()
prof = default_profile()
exp = float(sys.argv[1]) if len(sys.argv) > 1 else 1 / 30
gain = float(sys.argv[2]) if len(sys.argv) > 2 else 16
ages = [float(a) for a in sys.argv[3].split(",")] if len(sys.argv) > 3 else [30, 45, 60, 80, 100, 130]
sen = cam.sensor.replace(exposure_s=exp, gain=gain)
rng = np.random.default_rng(5)
dark = cam.median_dark(8, rng=rng, sensor=sen)
pipes = {
    "rows": Pipeline(prof, dark=dark),
    "free": Pipeline(prof, PipelineParams(rows=RowParams(anchored=False)), dark=dark),
    "none": Pipeline(prof, PipelineParams(rows=RowParams(enabled=False)), dark=dark),
}
for age in ages:
    st = {k: [0, 0, 0, 0] for k in pipes}
    for _ in range(20):
        s = cell_scene(rng, age_range_s=(age, age), box_prob=0.5, neighbour_mark_prob=0.6)
        f = cam.render(s.pose, rng=rng, phosphor=s.phosphor, red_lights_m=s.red_lights_m, board=s.board, sensor=sen)
        marked = {int(m["where"][3:]) for m in s.marks if m["where"].startswith("box")}
        nmarked = {m["where"] for m in s.marks if m["where"] in ("right", "forward", "left")}
        for key, p in pipes.items():
            o = p.process(f.image).observation
            for b in o.boxes:
                if b.box in marked:
                    st[key][0] += 1
                    st[key][1] += b.lit
                else:
                    st[key][2] += b.lit
            for n in ("right", "forward", "left"):
                if n in nmarked:
                    st[key][3] += o.neighbours[n].has_marks
    print(
        f"age {age:6.0f} s: {st['rows'][0]} marked boxes read with rows {st['rows'][1]}, free rows only "
        f"{st['free'][1]}, without {st['none'][1]}; unmarked read lit {st['rows'][2]} / {st['free'][2]} / "
        f"{st['none'][2]}; neighbour marks read {st['rows'][3]} / {st['free'][3]} / {st['none'][3]}"
    )
