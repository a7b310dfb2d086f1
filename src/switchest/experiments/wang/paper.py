"""What Wang, Yin, Lin, Polis & Chen (seed 003) print: the numbers of Examples 1-4 and of the
IEEE 5-bus case (§6), the one source of both reproductions' printed values.

Where a printed number comes from a misprinted formula, :mod:`.readings` evaluates that
formula.
"""

from __future__ import annotations

# Wang et al. §4.1-§5.2 (Examples 1-4); components 1-based as printed
EXAMPLES_PAPER = {
    "kb_gains": "L_1 = 2a_1, L_2 = 2a_2",  # §4.1: the ARE's Kalman-Bucy gains
    "gamma_bar_kb": (1.0794, 0.8836),  # §4.1: Kalman-Bucy gains L_i = 2 a_i
    "T_max": (0.0558, 0.2012),  # §4.3: ln(1/(1-p))/(2 a1), ln(1/p)/(2 a2)
    "gain_bounds": (25.7775, 6.3407),  # §4.3: L1 > ..., L2 > ... at T = 0.03
    "gamma_design": (0.9225, 0.6677),  # §4.3: gamma = max{...} for L1 = 40, L2 = 15
    "gamma1_example4": {30.0: 0.9883, 60.0: 0.9371, 100.0: 0.9126},  # §5.2
    "optimum": (61.3, 0.9864),  # §5.2, Fig. 6: L1*, sigma_inf^1(L1*, T)
    # §5.2 Example 3 prints expressions, no numbers: "T < ln 2/20" and "L_1 > -1/(2T) ln(2e^{-20T}
    # - 1)"
    "example3_T": "ln(2)/20",
    "example3_bound": "−ln(2e^(−20T) − 1)/(2T)",
}
DESIGN_GAINS = (40.0, 15.0)  # §4.3 Example 2 (Fig. 2, Fig. 3)
# Wang et al. §6 (Example 5); mode numbers 1-based as printed. A string keeps the printed digits
# where a trailing zero is printed ("-5.3880", "20.7170").
BUS_PAPER = {
    # printed {-5.3880, 5.2302, 0, -0.1253}, sorted descending here
    "eig_A": ("5.2302", "0", "-0.1253", "-5.3880"),
    "p": (0.985, 0.005, 0.01, 5e-5),
    "T_max": 0.7365,
    "T": 0.6997,
    "e0_norm": 2.2361,
    "gain": {"first": ("20.7170", "187.0468", "-123.7698", "-568.3264"),
             "aggressive": (41.7, 675.4, -681.6, -3181.7)},
    # eigenvalues of sum_i p_i Lambda(i)'Lambda(i), sorted descending (printed {0.9904, 0.54,
    # 0.0032, 0.0356})
    "moment_eig": {"first": (0.9904, 0.54, 0.0356, 0.0032),
                   "aggressive": (0.6891, 0.0046, 0.0015, 0.0001)},
    # §6: "M_1 = 1.9 and b_1 = 0.2 with equivalent time constant T_1 = M_1/b_1 = 9.5 s ... M_2 =
    # 0.9, b_1 = 0.16 with equivalent time constant T_2 = M_2/b_2 = 5.625 s" (the second "b_1" is
    # b_2)
    "generators": {"M": (1.9, 0.9), "b": (0.2, 0.16), "T": ("9.5", "5.625")},
    # the printed A: damping entries A[2,2], A[4,4] and couplings A[2,1], A[4,1] (1-based)
    "A_damping": ("-0.1053", "-0.1778"),
    "A_coupling": ("7.7926", "-20.3866"),
    # Table 1: line -> (R, X, |Z|, theta) as printed (p.u., rad); line 2-4's impedance is printed
    # "0.1941.25" in the text we have: 0.19∠1.25 with the ∠ lost
    "table1": {"1-2": ("0.02", "0.06", "0.06", "1.25"), "1-3": ("0.08", "0.24", "0.25", "1.25"),
               "2-3": ("0.06", "0.25", "0.26", "1.33"), "2-4": ("0.06", "0.18", "0.19", "1.25"),
               "2-5": ("0.04", "0.12", "0.13", "1.25"), "3-4": ("0.01", "0.03", "0.03", "1.25"),
               "4-5": ("0.08", "0.24", "0.25", "1.25")},
    # Table 3: sensors S_1, S_2 (state indices of [delta_1, omega_1, delta_2, omega_2]) -> printed
    # observability under: normal, S_1 fails, S_2 fails, both fail
    "table3": {("δ1", "δ2"): ("Yes", "Yes", "Yes", "No"),
               ("δ1", "ω1"): ("Yes", "No", "Yes", "No"),
               ("ω1", "ω2"): ("No", "No", "No", "No"),
               ("δ1", "ω2"): ("Yes", "No", "Yes", "No")},
}
