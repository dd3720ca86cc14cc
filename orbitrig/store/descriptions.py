"""What each name in an orbitrig HDF5 file means, its one list: each dataset's and each attribute's
units (a unit string pint parses, or a PER_* rule: one unit per entry) and description, and the
texts a writer puts beside them (an orbit's sign, the truth's convention, the power form).
orbitrig.store.annotate writes them onto every file.
"""

from __future__ import annotations

from orbitrig.store.layout import INTERVAL_BASIS_MEANING, MATRIX_NAMES
from rigunits import DAMPING, MASS, ONE, STIFFNESS

PER_CHANNEL, PER_COEFFICIENT, PER_SOURCE = "<channel>", "<coefficient>", "<source>"
#: the units attribute of a vector over the coefficients as the writers store it (their units: dataset units)
SI_PER_COEFFICIENT = "SI per coefficient (see dataset units)"
#: the description of a name missing from the catalog (the tests find none; a run never fails on it)
UNDOCUMENTED = "undocumented"

#: the sign of each ``orbit`` dataset (its attribute ``meaning``): an orbit table's rows and the
#: derived quantities' frequencies are |Omega| (the whirl direction is in the phasors), the
#: simulator's truth gives each row's Omega signed, as a block's ``orbit`` attribute does
ORBIT_TABLE = "|Omega| > 0: the whirl direction is in the phasors (y_bar = -i x_bar forward, +i x_bar backward)"
ORBIT_DERIVED = "|Omega| > 0, as planned"
ORBIT_SIGNED = "signed (< 0 backward)"
#: how the simulator's true Z is read beside its signed ``orbit`` (run.h5's ``Z`` attribute
#: ``convention``, run.mat's ``unit_rules.truth``, run.tdms's truth group): Z is a function of
#: |Omega|, one Z for both whirl directions at a speed, the direction being in d_bar
TRUTH_CONVENTION = (
    "f_bar = -Z d_bar with the orbit table's phasors (rows fx, fy; columns x, y); Z depends on |Omega| "
    "only, the whirl direction is in d_bar: Z = K + i|Omega| C - Omega^2 D for constant coefficients "
    "(not K + i Omega C - Omega^2 D at the signed orbit, its complex conjugate at a backward row)"
)
#: the paper's Eq. 15, the form of the truth's power best fit (run.h5's ``fits/power`` attribute ``form``)
POWER_FORM = "K = K0 + |Omega|^m Km, C = C0 + |Omega|^n Cn, D = D0 + |Omega|^p Dp (Eq. 15)"

#: dataset name -> (units, description); the units may be a PER_* rule
DATASETS = {
    "raw_counts": ("count", "every averaged revolution's A/D counts (revolution, channel, sample)"),
    "slots": ("degree", "slot of each sample (channel, sample): the orbit angle after the trigger, 1 slot = 1 degree"),
    "gains": (PER_CHANNEL + "/count", "calibration gain of each channel: value = gain x counts + offset"),
    "offsets": (PER_CHANNEL, "calibration offset of each channel"),
    "mean": (PER_CHANNEL, "synchronous average over the revolutions (channel, sample)"),
    "dc": (PER_CHANNEL, "mean value of each channel over the revolution"),
    "rms_residual": (PER_CHANNEL, "RMS of the average minus its dc and fundamental"),
    "record_phasors": (
        PER_CHANNEL,
        "each revolution's fundamental phasor (revolution, channel), q = Re(q_bar exp(i theta))",
    ),
    "phasors": (PER_CHANNEL, "fundamental phasor of the average, q = Re(q_bar exp(i theta))"),
    "uncertainty": (PER_CHANNEL, "standard uncertainty of each averaged phasor, the spin tones fitted out"),
    "revolutions": (ONE, "the A/D board's revolution number of each averaged revolution"),
    "coherence": (ONE, "gamma^2 between displacement and force: rows piezo, strain; columns xfx, yfx, xfy, yfy"),
    "orbit": ("rad/s", "orbit speed Omega (its sign: attribute meaning)"),
    "orbit_hz": ("Hz", "orbit frequency"),
    "x": ("m", "x displacement phasor of the journal (mean of the probe planes)"),
    "y": ("m", "y displacement phasor of the journal (mean of the probe planes)"),
    "fx": ("N", "x force phasor on the journal"),
    "fy": ("N", "y force phasor on the journal"),
    "gamma2": (ONE, "coherences of each row: columns xfx, yfx, xfy, yfy"),
    "n_records": (ONE, "revolutions averaged behind each row"),
    "u": ("<column>", "standard uncertainty of each averaged phasor: columns x, y, fx, fy"),
    "names": ("", "coefficient keys"),
    "units": ("", "SI unit of each coefficient"),
    "notes": ("", "notes of the identification"),
    "warnings": ("", "warnings of the identification"),
    "coefficients": (PER_COEFFICIENT, "identified coefficients, aligned with names"),
    "std_errors": (PER_COEFFICIENT, "standard error of each coefficient (one standard deviation)"),
    "interval_95": (
        PER_COEFFICIENT,
        "value -+ U (expanded uncertainty, k x the standard uncertainty named by interval_95_basis): columns low, high",
    ),
    "interval_95_statistical": (PER_COEFFICIENT, "two-sided 95 % interval, statistical only: columns low, high"),
    "covariance": (
        PER_COEFFICIENT,
        "covariance of the free coefficients (attribute names); entry (i, j) in units_<name_i> x units_<name_j>",
    ),
    "statistical": (PER_COEFFICIENT, "standard uncertainty from the fit (type A)"),
    "systematic": (
        PER_COEFFICIENT,
        "standard uncertainty from the stated calibration (type B), and from the subtracted runout when recorded",
    ),
    "combined": (PER_COEFFICIENT, "combined standard uncertainty"),
    "expanded": (PER_COEFFICIENT, "expanded uncertainty U = k x combined, k of k_values"),
    "k_values": ("1", "coverage factor k of each coefficient's U: Student's t at 95.45 % at effective_dof"),
    "effective_dof": ("1", "Welch-Satterthwaite effective degrees of freedom of the combined u (inf: all parts exact)"),
    "runout": (PER_COEFFICIENT, "standard uncertainty from the subtracted runout (type B, inside systematic)"),
    "runout_covariance": (
        PER_COEFFICIENT,
        "covariance of the free coefficients (attribute names) from the subtracted runout (type B, inside "
        "systematic); entry (i, j) in units_<name_i> x units_<name_j>",
    ),
    "sources": ("", "calibration error parameters propagated"),
    "source_std": (PER_SOURCE, "stated standard uncertainty of each calibration error parameter"),
    "source_dof": ("1", "degrees of freedom of each source's stated u (inf: exact); with source_std they rebuild k"),
    "e_n": (ONE, "normalised difference piezo - strain against its uncertainty"),
    "c_eff_xx": (DAMPING, "effective damping C_xx - K_xy/Omega"),
    "c_eff_yy": (DAMPING, "effective damping C_yy + K_yx/Omega"),
    "c_eff_xx_std": (DAMPING, "standard uncertainty of c_eff_xx"),
    "c_eff_yy_std": (DAMPING, "standard uncertainty of c_eff_yy"),
    "c_eff_zero_xx": ("rad/s", "orbit speed where c_eff_xx crosses zero, and its standard uncertainty"),
    "c_eff_zero_yy": ("rad/s", "orbit speed where c_eff_yy crosses zero, and its standard uncertainty"),
    "h_forward": (STIFFNESS, "forward-whirl direct dynamic stiffness H"),
    "h_backward": (STIFFNESS, "backward-whirl direct dynamic stiffness H"),
    "h_forward_std": (STIFFNESS, "standard uncertainty of h_forward: columns re, im"),
    "h_backward_std": (STIFFNESS, "standard uncertainty of h_backward: columns re, im"),
    "wfr": (ONE, "whirl frequency ratio"),
    "wfr_std": (ONE, "standard uncertainty of wfr"),
    "Z": (
        "N/m",
        "the simulator's true impedance at each row's |Omega| (attribute convention), f_bar = -Z d_bar (row, force, displacement)",
    ),
    "band": ("rad/s", "the |Omega| the best fits use"),
    "K": (STIFFNESS, MATRIX_NAMES["K"]),
    "C": (DAMPING, MATRIX_NAMES["C"]),
    "D": (MASS, MATRIX_NAMES["D"]),
    "K0": (STIFFNESS, "constant stiffness term"),
    "C0": (DAMPING, "constant damping term"),
    "D0": (MASS, "constant mass term"),
    "Km": ("N/m (rad/s)^-{m}", "stiffness term multiplying |Omega|^m (attribute exponents)"),
    "Cn": ("N s/m (rad/s)^-{n}", "damping term multiplying |Omega|^n (attribute exponents)"),
    "Dp": ("kg (rad/s)^-{p}", "mass term multiplying |Omega|^p (attribute exponents)"),
    "channels": ("", "A/D channel names in board order"),
    "channel_units": ("", "unit of each A/D channel"),
    "events": ("<field>", "the run's events: t (s since the run started), state, message"),
    "can": ("<field>", "CAN sensor node log"),
    "drives": ("<field>", "drive log"),
    "commands": ("<field>", "every command that changed the run: at (ISO 8601 UTC), command, by (who sent it), detail"),
    "expanded_uncertainty": (PER_COEFFICIENT, "expanded uncertainty U by names (attribute k: the largest; basis)"),
    "expanded_k": ("1", "coverage factor k of each coefficient's expanded uncertainty U, aligned with names"),
    "coefficient_names": ("", "the coefficients a sequential decision judged, aligned with before and after"),
    "before": (
        "1",
        "each coefficient's predicted relative standard error (standard error / scale) before the decision",
    ),
    "after": (ONE, "each coefficient's predicted relative standard error after the chosen block"),
    "not_determined": (ONE, "1 where the coefficient's expanded uncertainty exceeds its magnitude (not determined)"),
    "truth": (
        PER_COEFFICIENT,
        "the simulator's true impedance projected onto this fit's model (same table, weights, "
        "constraints, method), aligned with names",
    ),
}

#: attribute name -> (units, description); "" units: text
ATTRIBUTES = {
    "format": ("", "file format and version"),
    "software_version": ("", "software that wrote the file"),
    "software_versions": (
        "",
        "JSON list: the software that measured the points, in point order (two or more: resumed with other software)",
    ),
    "software": ("", "software that measured the point"),
    "created": ("", "creation time, ISO 8601 UTC"),
    "status": ("", "run status"),
    "status_message": ("", "why the run ended"),
    "sim": (ONE, "true for a run on the simulator"),
    "rig_config": ("", "rig configuration (TOML text)"),
    "matrix_config": ("", "test matrix (TOML text)"),
    "matrix_name": ("", "test matrix name"),
    "sim_scenario_name": ("", "simulator scenario"),
    "sim_scenario_config": ("", "simulator scenario (TOML text)"),
    "index": (ONE, "operating point index in plan order"),
    "complete": (ONE, "true when complete"),
    "spin": ("rad/s", "journal spin speed omega"),
    "spin_rpm": ("rpm", "journal spin speed"),
    "recess_pressure": ("Pa", "recess pressure"),
    "pressure_ratio": (ONE, "recess / supply pressure"),
    "static_eccentricity": (ONE, "static eccentricity / clearance"),
    "dynamic_eccentricity": (ONE, "orbit radius / clearance"),
    "orbit_radius": ("m", "commanded orbit radius"),
    "label": ("", "operating point label"),
    "orbit": ("rad/s", "orbit speed Omega, signed: < 0 backward whirl"),
    "orbit_hz": ("Hz", "orbit frequency, > 0"),
    "direction": (ONE, "+1 forward, -1 backward whirl"),
    "measured_orbit_speed": ("rad/s", "orbit speed from the trigger times"),
    "spin_written": ("rad/s", "spin speed as written to the drive (its REF count), NaN: not known"),
    "orbit_written": ("rad/s", "orbit speed as written to the drive (its REF count), signed, NaN: not known"),
    "n_records": (ONE, "revolutions averaged"),
    "stop_reason": ("", "why averaging stopped: count, target or max"),
    "spin_turns": (ONE, "spin turns per board revolution the spin tones were fitted out at"),
    "spin_turns_basis": ("", "that ratio: fitted (the block's own, resolved) or commanded"),
    "channels": ("", "A/D channel names"),
    "channel_units": ("", "unit of each A/D channel"),
    "frames_good": (ONE, "A/D frames decoded"),
    "frames_bad": (ONE, "damaged A/D frames"),
    "bytes_skipped": ("byte", "bytes skipped while resynchronising"),
    "link_drops": (ONE, "A/D link drops"),
    "frames_lost": (ONE, "A/D frames missing from the stream (frame counter jumps)"),
    "revolutions_used": (ONE, "revolutions averaged"),
    "revolutions_dropped": (ONE, "revolutions dropped"),
    "drop_reasons": ("", "dropped revolutions by reason (JSON)"),
    "frame_errors": ("", "frame errors by kind (JSON)"),
    "model": ("", "impedance model"),
    "freq_dep": ("", "frequency dependence"),
    "method": ("", "estimation method"),
    "error": ("", "why this could not be evaluated"),
    "json": ("", "the whole result as JSON"),
    "n_coefficients": (ONE, "coefficients identified"),
    "min_frequencies": (ONE, "orbit frequencies the model needs"),
    "n_frequencies": (ONE, "orbit frequencies used"),
    "condition_number": (ONE, "condition number of the regression"),
    "residual_rms": ("N", "RMS force residual"),
    "dof": (ONE, "degrees of freedom"),
    "chi2": (ONE, "chi-square of the fit, or of the two load measuring systems' joint difference"),
    "p_value": (ONE, "p-value"),
    "aic": (ONE, "Akaike information criterion"),
    "bic": (ONE, "Bayesian information criterion"),
    "exponent": (ONE, "exponent chosen by power:auto"),
    "k": (ONE, "coverage factor of the expanded uncertainty"),
    "interval_95_basis": ("", INTERVAL_BASIS_MEANING),
    "covariance": ("", "covariance behind the standard uncertainties: combined or statistical"),
    "max_abs": (ONE, "largest |E_n|"),
    "consistent": (ONE, "true when chi2 <= limit: the two systems agree on all coefficients at the family-wise level"),
    "limit": (
        "1",
        "chi2(dof) quantile at 1 - level (a run stored before the joint test: the largest consistent |E_n|)",
    ),
    "level": (ONE, "family-wise probability that two consistent systems are flagged (0.05)"),
    "basis": ("", "uncertainty the comparison uses"),
    "pair": ("", "the systems compared"),
    "verdict": ("", "frequency dependence supported or not"),
    "supported": (ONE, "true when the test supports it"),
    "statistic": (ONE, "test statistic"),
    "test": ("", "F, likelihood ratio, or chi2 (the two systems' joint test)"),
    "alpha": (ONE, "significance level"),
    "constant": ("", "the constant fit compared with"),
    "aic_bic_order": ("", "the fits the aic and bic pairs belong to"),
    "exponents": (ONE, "exponents m, n, p"),
    "form": ("", "the fitted form"),
    "operator": ("", "who ran the run"),
    "rig_id": ("", "the rig's id (rig.toml)"),
    "host": ("", "computer that ran it"),
    "calibration_record": (
        "",
        "active calibration record: NAME of NAME.toml in the calibration/ folder beside rig.toml "
        "(its text: calibration_record_text)",
    ),
    "calibration_record_sha256": ("", "SHA-256 of the calibration record's text"),
    "calibration_record_seal": (
        "",
        "whether the record's text was as its step wrote it (its SHA-256 line): as written, not verifiable",
    ),
    "calibration_validity": (
        "",
        "the record's measurements against rig.toml's calibration_valid_days at the run's start: "
        "expired, valid or no limit, then each part's age",
    ),
    "rig_sha256": ("", "SHA-256 of rig.toml's text as read (rig_config)"),
    "matrix_sha256": (
        "",
        "SHA-256 of the matrix file's text as read (matrix_config without the [design_used] table a run appends)",
    ),
    "calibration_record_text": ("", "the calibration record (TOML text)"),
    "sensor_serials": ("", "serial number of each channel's sensor (JSON)"),
    "started": ("", "run start, ISO 8601 UTC"),
    "ended": ("", "run end, ISO 8601 UTC"),
    "definition": ("", "how the truth was obtained"),
    "reason": ("", "why the sequential design chose this block (next) or stopped (target, cap)"),
    "ratio": (ONE, "orbit ratio |Omega|/omega chosen (nan: stopped)"),
    "whirl": ("", "forward, backward or both"),
    "revolutions": (ONE, "revolutions chosen"),
    "seconds": ("s", "rig seconds the chosen block takes"),
    "spent_s": ("s", "rig seconds of the point's blocks before the decision"),
}
