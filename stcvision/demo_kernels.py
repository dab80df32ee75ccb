# ruff: noqa: E501 (numba's argument types, one kernel a line)
"""The numba kernels the demo compiles on its first run (those it calls from Python and
those they call), with their argument types as numba writes them, in the order their
compiles start: written by ``python -m stcvision.warm --record-demo``, checked against what
the demo loads by ``tests/stcvision/test_warm.py``. On the demo's first run a second process
compiles them from the last (:func:`stcvision.warm.compile_from_the_end`) while the demo
compiles them from the first."""

#: (module, the name the kernel has there, its argument types), one kernel a line, as the
#: recording writes it
# fmt: off
DEMO_KERNELS = (
    ('stcvision.sim_camera.optics', '_project_nb', "(Array(float64, 2, 'C', False, aligned=True), float64, Array(float64, 3, 'C', False, aligned=True), float64, float64, Array(float64, 3, 'C', True, aligned=True), Array(float64, 1, 'C', False, aligned=True), int64, Array(float64, 2, 'C', False, aligned=True), Array(bool, 1, 'C', False, aligned=True))"),
    ('stcvision.sim_camera.optics', '_nearest_pixel', '(float64, float64, int64, int64)'),
    ('stcvision.sim_camera.optics', '_newton_step_nb', "(float64, float64, float64, float64, float64, float64, float64, float64, Array(float64, 1, 'C', False, aligned=True))"),
    ('stcvision.sim_camera.optics', '_trace_uv_nb', "(float64, float64, Array(float64, 1, 'C', False, aligned=True))"),
    ('stcvision.sim_camera.camera', '_geometry_nb', "(Array(float64, 2, 'C', True, aligned=True), Array(bool, 1, 'C', True, aligned=True), Array(float64, 1, 'C', False, aligned=True), Array(float64, 3, 'C', True, aligned=True), float64, Array(int64, 1, 'C', False, aligned=True), Array(int64, 2, 'C', False, aligned=True), Array(float64, 2, 'C', False, aligned=True), Array(float64, 3, 'C', False, aligned=True), Array(float64, 3, 'C', False, aligned=True))"),
    ('stcvision.sim_camera.camera', '_inv2_nb', '(float64, float64, float64, float64)'),
    ('stcvision.sim_camera.camera', '_splat_nb', "(Array(float32, 3, 'C', False, aligned=True), Array(int64, 1, 'C', False, aligned=True), Array(int64, 1, 'C', False, aligned=True), Array(float64, 2, 'C', False, aligned=True), Array(float64, 3, 'C', False, aligned=True), Array(float64, 1, 'C', False, aligned=True), Array(float64, 1, 'C', False, aligned=True), Array(float64, 3, 'C', False, aligned=True))"),
    ('stcvision.sim_camera.camera', '_spill_all_nb', "(Array(float32, 3, 'C', False, aligned=True), Array(int64, 1, 'C', False, aligned=True), Array(int64, 1, 'C', False, aligned=True), int64, Array(float64, 2, 'C', False, aligned=True), Array(float64, 2, 'C', False, aligned=True), Array(float64, 2, 'C', False, aligned=True), Array(float64, 2, 'C', False, aligned=True))"),
    ('stcvision.sim_camera.camera', '_spill_nb', "(Array(float32, 3, 'C', False, aligned=True), int64, int64, int64, int64, int64, int64, Array(float64, 2, 'C', False, aligned=True), Array(float64, 2, 'C', False, aligned=True), Array(float64, 1, 'C', False, aligned=True), Array(float64, 1, 'C', False, aligned=True))"),
    ('stcvision.sim_camera.image_sensor', '_expose_nb', "(Array(float32, 1, 'C', False, aligned=True), Array(float32, 1, 'C', False, aligned=True), bool, Array(float32, 1, 'C', False, aligned=True), bool, Array(float32, 1, 'C', False, aligned=True), Array(float32, 1, 'C', False, aligned=True), Array(float32, 1, 'C', False, aligned=True), Array(uint16, 1, 'C', False, aligned=True), Array(float32, 1, 'C', False, aligned=True), float32, float32, float32)"),
    ('stcvision.stages.dark', 'sample_quartiles', "(Array(uint8, 1, 'C', False, aligned=True), Array(int64, 1, 'C', False, aligned=True), Array(uint8, 1, 'C', False, aligned=True), Array(uint8, 1, 'C', False, aligned=True), Array(bool, 1, 'C', False, aligned=True), Array(bool, 1, 'C', False, aligned=True), int64, int64, int64, bool, Array(uint8, 1, 'C', False, aligned=True), Array(uint8, 1, 'C', False, aligned=True))"),
    ('stcvision.stages.dark', '_quartiles_of', "(Array(uint8, 1, 'C', False, aligned=True), int64, bool)"),
    ('stcvision.stages.dark', 'histogram_quartiles', "(Array(uint8, 1, 'C', False, aligned=True), Literal[int](0), Literal[int](1), Literal[int](256))"),
    ('stcvision.stages.dark', 'histogram_quartiles', "(Array(uint8, 1, 'C', False, aligned=True), int64, int64, int64)"),
    ('stcvision.stages.window', 'box3_pair', "(Array(uint8, 1, 'C', False, aligned=True), Array(uint8, 1, 'C', False, aligned=True), int64, int64, Array(uint16, 1, 'C', False, aligned=True), Array(uint16, 1, 'C', False, aligned=True))"),
    ('stcvision.stages.ground_view', 'unwarp_separate_u16', "(Array(uint32, 1, 'C', False, aligned=True), int64, Array(int32, 1, 'C', False, aligned=True), Array(float32, 1, 'C', False, aligned=True), Array(float32, 1, 'C', False, aligned=True), UniTuple(float32, 7), Array(uint16, 1, 'C', False, aligned=True), Array(uint16, 1, 'C', False, aligned=True), Array(uint8, 1, 'C', False, aligned=True), Array(uint64, 2, 'C', False, aligned=True))"),
    ('stcvision.stages.ground_view', 'unwarp_border', "(Array(uint16, 1, 'C', False, aligned=True), int64, int64, Array(int64, 1, 'C', False, aligned=True), Array(float32, 2, 'C', False, aligned=True), bool, UniTuple(float32, 7), Array(uint16, 1, 'C', False, aligned=True), Array(uint16, 1, 'C', False, aligned=True), Array(uint8, 1, 'C', False, aligned=True))"),
    ('stcvision.stages.channels', 'zero_where', "(Array(uint16, 1, 'C', False, aligned=True), Array(uint8, 1, 'C', False, aligned=True))"),
    ('stcvision.stages.dots', 'dot_candidates', "(Array(uint16, 2, 'C', False, aligned=True), Array(float32, 2, 'C', False, aligned=True), int64, float64, float64, int64, int64, float64, float64)"),
    ('stcvision.stages.dots', 'rank_dots', "(Array(int64, 1, 'C', False, aligned=True), Array(int64, 1, 'C', False, aligned=True), Array(float64, 1, 'C', False, aligned=True), Array(float64, 1, 'C', False, aligned=True), int64, float64, int64, int64, Array(uint16, 2, 'C', False, aligned=True), int64, float64)"),
    ('stcvision.stages.dots', 'greedy_black_out', "(Array(int64, 1, 'C', False, aligned=True), Array(int64, 1, 'C', False, aligned=True), Array(float64, 1, 'C', False, aligned=True), int64, float64, int64)"),
    ('stcvision.stages.dots', 'window_centroids', "(Array(uint16, 2, 'C', False, aligned=True), Array(int64, 1, 'C', False, aligned=True), Array(int64, 1, 'C', False, aligned=True), int64, float64)"),
    ('stcvision.stages.dots', 'map_at', "(Array(float32, 2, 'C', False, aligned=True), Array(float32, 2, 'C', False, aligned=True), Array(float64, 2, 'C', False, aligned=True), Array(float64, 2, 'C', False, aligned=True), float64)"),
    ('stcvision.stages.dots', 'gauss_centroids', "(Array(uint8, 2, 'C', False, aligned=True), Array(float64, 2, 'A', False, aligned=True), float64, int64, float64, int64)"),
    ('stcvision.stages.dots', 'mirror_shift', "(Array(float64, 3, 'C', False, aligned=True), Array(float64, 2, 'C', False, aligned=True), Array(bool, 1, 'C', False, aligned=True), Array(float64, 2, 'C', False, aligned=True), float64)"),
    ('stcvision.stages.rows', 'row_snr', "(Array(uint16, 2, 'C', False, aligned=True), Array(float32, 2, 'C', False, aligned=True), int64, float64, float64, float64, Array(float32, 2, 'C', False, aligned=True))"),
    ('stcvision.stages.rows', 'zero_ring', "(Array(uint16, 2, 'C', False, aligned=True), int64, Array(uint8, 2, 'C', False, aligned=True))"),
    ('stcvision.stages.rows', 'blur_squares', "(Array(uint8, 2, 'C', False, aligned=True), Array(float64, 2, 'C', False, aligned=True), Array(float64, 1, 'C', False, aligned=True), Array(bool, 1, 'C', False, aligned=True), float64, int64)"),
    ('stcvision.stages.rows', 'free_rows', "(Array(float32, 2, 'C', False, aligned=True), Array(uint8, 2, 'C', False, aligned=True), Array(int64, 1, 'C', True, aligned=True), Array(int64, 1, 'C', True, aligned=True), int64, float64, float64, float64, float64, float64, Array(uint8, 2, 'C', False, aligned=True))"),
    ('stcvision.stages.red', 'nonzero_mask', "(Array(uint16, 2, 'C', False, aligned=True), Array(uint8, 2, 'C', False, aligned=True))"),
    ('stcvision.stages.red', 'blobs', "(Array(uint16, 2, 'C', False, aligned=True), Array(int32, 2, 'C', False, aligned=True), Array(int64, 1, 'C', False, aligned=True), float64, float64)"),
    ('stcvision.observation', 'homography', "(Array(float64, 2, 'C', False, aligned=True), Array(float64, 2, 'C', False, aligned=True))"),
    ('stcvision.observation', 'cell_dots', "(Array(float64, 2, 'C', False, aligned=True), Array(bool, 1, 'C', False, aligned=True), float64, float64, float64, int64)"),
    ('stcvision.observation', 'row_orientation_loop', "(Array(float64, 2, 'C', False, aligned=True), float64, float64)"),
    ('stcvision.observation', 'mark_offset_loop', "(Array(float64, 2, 'C', False, aligned=True), Array(int64, 1, 'C', False, aligned=True), Array(bool, 1, 'C', False, aligned=True), float64, int64)"),
    ('stcvision.observation', 'assign_boxes_loop', "(Array(float64, 2, 'C', False, aligned=True), Array(int64, 1, 'C', False, aligned=True), Array(int64, 2, 'C', False, aligned=True), Array(int64, 3, 'C', False, aligned=True), Array(int64, 2, 'C', False, aligned=True))"),
    ('stcvision.observation', 'box_counts', "(Array(int64, 1, 'C', False, aligned=True), Array(int64, 1, 'C', False, aligned=True), Array(int64, 1, 'C', False, aligned=True), Array(bool, 1, 'C', False, aligned=True), Array(float64, 1, 'C', False, aligned=True))"),
    ('stcvision.observation', 'group_stats_loop', "(Array(int64, 1, 'C', False, aligned=True), Literal[int](9), Array(bool, 1, 'C', False, aligned=True), Array(float64, 1, 'C', False, aligned=True))"),
    ('stcvision.observation', 'group_stats_loop', "(Array(int64, 1, 'C', False, aligned=True), Literal[int](5), Array(bool, 1, 'C', False, aligned=True), Array(float64, 1, 'C', False, aligned=True))"),
    ('stcvision.observation', 'landing_counts', "(Array(float64, 2, 'C', False, aligned=True), Array(bool, 1, 'C', False, aligned=True), Array(float64, 2, 'C', False, aligned=True), float64)"),
    ('stcvision.observation', 'group_stats_loop', "(Array(int64, 1, 'C', False, aligned=True), int64, Array(bool, 1, 'C', False, aligned=True), Array(float64, 1, 'C', False, aligned=True))"),
    ('stcvision.localisation', 'rotate_about', "(Array(float64, 2, 'C', False, aligned=True), float64, float64, float64, float64)"),
    ('stcvision.stages.dots', 'gauss_centroids', "(Array(uint8, 2, 'C', False, aligned=True), Array(float64, 2, 'C', False, aligned=True), float64, int64, float64, int64)"),
    ('stcvision.stages.rows', 'crowded_dots', "(Array(float64, 2, 'C', False, aligned=True), float64)"),
    ('stcvision.stages.rows', 'anchored_rows', "(Array(float32, 2, 'C', False, aligned=True), Array(uint8, 2, 'C', False, aligned=True), Array(float64, 2, 'C', False, aligned=True), Array(float64, 1, 'C', False, aligned=True), Array(bool, 1, 'C', False, aligned=True), float64, int64, float64, int64, float64, float64, float64, float64)"),
    ('stcvision.stages.rows', '_taken', "(Array(uint8, 2, 'C', False, aligned=True), Array(int64, 1, 'C', False, aligned=True), Array(int64, 1, 'C', False, aligned=True))"),
    ('stcvision.stages.heading', 'heading_row', "(Array(float64, 2, 'C', False, aligned=True), Array(float64, 1, 'C', False, aligned=True), int64, float64, float64)"),
    ('stcvision.stages.heading', 'tls_line', "(Array(float64, 2, 'C', False, aligned=True),)"),
    ('stcvision.stages.rows', 'row_dots', "(Array(uint16, 2, 'C', False, aligned=True), Array(float32, 2, 'C', False, aligned=True), Array(float32, 2, 'C', False, aligned=True), Array(float64, 2, 'C', False, aligned=True), int64, float64, float64)"),
    ('stcvision.stages.rows', 'accept_free_rows', "(UniTuple(int64, 2), Array(float64, 3, 'C', False, aligned=True), Array(int64, 1, 'C', False, aligned=True), Array(int64, 1, 'C', False, aligned=True), Array(float32, 1, 'C', False, aligned=True), Array(int64, 1, 'C', False, aligned=True), Array(int64, 1, 'C', True, aligned=True), int64, int64)"),
    ('stcvision.stages.rows', 'accept_rows', "(Array(uint8, 2, 'C', False, aligned=True), Array(int64, 1, 'C', False, aligned=True), Array(int64, 1, 'C', False, aligned=True), Array(int64, 1, 'C', False, aligned=True), Array(int64, 1, 'C', False, aligned=True), Array(int64, 1, 'C', True, aligned=True), int64, int64)"),
)
# fmt: on
