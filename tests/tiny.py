"""Tiny inputs that several test folders share: they run in a fraction of a second."""

#: A two-minute tow over a small floor: enough for a whole run folder, fast enough for dozens of cases.
TINY_SCENARIO = """
name = "tiny"
seed = 3
duration_s = 60
[terrain]
shape = [120, 160]
node_m = 10.0
roughness_m = 10.0
hurst = 0.5
[ship]
waypoints_m = [[900.0, 600.0], [1500.0, 600.0]]
[cable]
out_m = 1200.0
[navigation]
search_half_width_m = 100.0
"""
