"""Every number the paper reports that the product compares itself with — in one place.

Units are in the key names.  Sources are the paper's sections, tables and figures as cited.
"""

#: Sec. IV-A, Fig. 4 — workspace of tendon-driven (TD) vs tendon-pneumatic (TPHD) actuation.
WORKSPACE = {"samples_per_mode": 10_000, "increase_percent": 108.6, "tension_range_N": (0.0, 5.0),
             "pressure_range_Pa": (0.0, 120e3)}

#: Sec. V-C, Fig. 9 — stiffness with locked tendons vs constant tension.
STIFFNESS = {"locked_over_constant": 2.0, "note": "\"about twice\" (Sec. V-C; Fig. 9 values not tabulated)",
             "mean_error_vs_measured_percent": {"0 kPa": 3.1, "25 kPa": 5.0, "50 kPa": 3.0}}

#: Sec. IV-B, Table I — tip error after 5 iterations under stochastic loads.
TABLE1 = {"upward": {"vfcc_mm": 9.054, "lacc_mm": 0.020, "reduction_percent": 99.78},
          "horizontal": {"vfcc_mm": 10.23, "lacc_mm": 0.028, "reduction_percent": 99.73},
          "downward": {"vfcc_mm": 2.090, "lacc_mm": 0.006, "reduction_percent": 99.71}}
TABLE1_REDUCTION_PERCENT_MIN = 99.71

#: Sec. IV-B — IK-derived vs FK-derived compliance inside LACC.
ABLATION = {"ik_faster_percent": 50.0}

#: Sec. V-D/E — loading experiments.
LOADING = {"continuous_max_error_mm": 0.722, "cyclic_max_error_mm": 3.573, "loop_time_s": 0.5,
           "continuous_uncontrolled_drift_mm": 10.0, "cyclic_uncontrolled_drift_mm": 7.0}

#: The legacy nested view used by the studies' printed tables.
PAPER = {"workspace": WORKSPACE, "stiffness": STIFFNESS,
         "table1": {**TABLE1, "reduction_percent_min": TABLE1_REDUCTION_PERCENT_MIN},
         "ablation": ABLATION}
