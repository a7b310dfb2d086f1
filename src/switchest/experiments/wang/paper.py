"""What Wang, Yin, Lin, Polis & Chen (seed 003) print: the numbers of Examples 1-4 and of the
IEEE 5-bus case (§6), the one source of both reproductions' printed values.

Where a printed number comes from a misprinted formula, :mod:`.readings` evaluates that
formula.
"""

from __future__ import annotations

import numpy as np

# Wang et al. §4.1-§5.2 (Examples 1-4); components 1-based as printed
EXAMPLES_PAPER = {
    "gamma_bar_kb": (1.0794, 0.8836),  # §4.1: Kalman-Bucy gains L_i = 2 a_i
    "T_max": (0.0558, 0.2012),  # §4.3: ln(1/(1-p))/(2 a1), ln(1/p)/(2 a2)
    "gain_bounds": (25.7775, 6.3407),  # §4.3: L1 > ..., L2 > ... at T = 0.03
    "gamma_design": (0.9225, 0.6677),  # §4.3: gamma = max{...} for L1 = 40, L2 = 15
    "gamma1_example4": {30.0: 0.9883, 60.0: 0.9371, 100.0: 0.9126},  # §5.2
    "optimum": (61.3, 0.9864),  # §5.2, Fig. 6: L1*, sigma_inf^1(L1*, T)
    "example3_T": float(np.log(2.0) / 20.0),  # §5.2: printed "T < ln(2)/20"
}
DESIGN_GAINS = (40.0, 15.0)  # §4.3 Example 2 (Fig. 2, Fig. 3)
# Wang et al. §6 (Example 5); mode numbers 1-based as printed
BUS_PAPER = {
    "eig_A": (5.2302, 0.0, -0.1253, -5.3880),  # printed {-5.3880, 5.2302, 0, -0.1253}, sorted here
    "p": (0.985, 0.005, 0.01, 5e-5),
    "T_max": 0.7365,
    "T": 0.6997,
    "e0_norm": 2.2361,
    "gain": {"first": (20.7170, 187.0468, -123.7698, -568.3264),
             "aggressive": (41.7, 675.4, -681.6, -3181.7)},
    # eigenvalues of sum_i p_i Lambda(i)'Lambda(i), sorted descending (printed {0.9904, 0.54,
    # 0.0032, 0.0356})
    "moment_eig": {"first": (0.9904, 0.54, 0.0356, 0.0032),
                   "aggressive": (0.6891, 0.0046, 0.0015, 0.0001)},
}
