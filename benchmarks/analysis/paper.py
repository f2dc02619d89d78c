"""The paper's published figures (SCTN paper, Tables 2 and 3), one source for every table that sets ours beside them.

Table 2 gives A and R per test sequence and ARscore beneath them, each rounded to three places; its ARscore
follows from A and R by the metric's formula to within that rounding (tested). Table 3 gives SCTN's
accumulate operations per evaluation and SiamRPN's and SiamMask's multiply-accumulates per frame.
"""

from __future__ import annotations

# tracker -> sequence -> (A, R, ARscore), as printed; "all" pools the five test sequences
TABLE2: dict[str, dict[str, tuple[float, float, float]]] = {
    "rct": {"city_cat": (0.054, 0.020, 0.023), "city_bottle": (0.014, 0.014, 0.014),
            "city_star": (0.344, 0.130, 0.149), "sky_cube": (0.435, 0.294, 0.315),
            "woman_ball": (0.114, 0.102, 0.104), "all": (0.223, 0.135, 0.147)},
    "goturn": {"city_cat": (0.511, 0.490, 0.494), "city_bottle": (0.643, 0.890, 0.827),
               "city_star": (0.532, 0.554, 0.550), "sky_cube": (0.597, 0.773, 0.730),
               "woman_ball": (0.522, 0.636, 0.609), "all": (0.562, 0.681, 0.653)},
    "siamrpn": {"city_cat": (0.767, 0.980, 0.928), "city_bottle": (0.700, 0.959, 0.893),
                "city_star": (0.754, 0.978, 0.923), "sky_cube": (0.838, 0.992, 0.956),
                "woman_ball": (0.819, 0.983, 0.945), "all": (0.786, 0.980, 0.934)},
    "siammask": {"city_cat": (0.749, 0.980, 0.923), "city_bottle": (0.721, 0.973, 0.909),
                 "city_star": (0.775, 0.957, 0.914), "sky_cube": (0.814, 1.000, 0.956),
                 "woman_ball": (0.863, 0.992, 0.963), "all": (0.797, 0.982, 0.939)},
    "ocean": {"city_cat": (0.577, 0.653, 0.636), "city_bottle": (0.535, 0.562, 0.556),
              "city_star": (0.581, 0.717, 0.685), "sky_cube": (0.564, 0.681, 0.654),
              "woman_ball": (0.670, 0.890, 0.835), "all": (0.592, 0.721, 0.691)},
    "automatch": {"city_cat": (0.631, 0.755, 0.726), "city_bottle": (0.620, 0.795, 0.752),
                  "city_star": (0.661, 0.880, 0.826), "sky_cube": (0.682, 0.891, 0.839),
                  "woman_ball": (0.728, 0.932, 0.883), "all": (0.674, 0.869, 0.822)},
    "sctn": {"city_cat": (0.788, 0.939, 0.904), "city_bottle": (0.762, 0.959, 0.912),
             "city_star": (0.739, 0.946, 0.896), "sky_cube": (0.805, 0.992, 0.948),
             "woman_ball": (0.769, 0.949, 0.907), "all": (0.773, 0.960, 0.916)},
}

SCTN_AC_PER_EVALUATION = 7.69e6  # Table 3: SCTN's accumulate operations for one candidate evaluation
SIAMESE_MAC_PER_FRAME = {"SiamRPN": 4.82e9, "SiamMask": 1.26e10}  # Table 3: multiply-accumulates per frame
