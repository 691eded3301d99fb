#!/usr/bin/python3
"""Dissipated power and first-harmonic container force from a LIGGGHTS force_log.txt.

Input: the file of `fix ave/time 1 N N f_box[1] f_box[2] f_box[3] v_power_in` (run_liggghts.sh with
SAMPLE_EVERY=N): each row averages steps step-N+1..step of
  F = f_box, the force the particles put on the box (N; LIGGGHTS fix mesh/surface/stress), and
  power_in = -F_x v_box, the power the box puts into the particles (W), v_box = A w cos(w t).
Box motion x_box = A sin(w t), w = 2 pi f.

Conventions of the output:
  P = mean(F_box_on_particles . v_box) = mean(-F_x v_box) > 0 when the particles dissipate.
  F_x ~ F1 sin(w t + phi): F1 and phi are the first harmonic of the force ON THE BOX (pdsim's
  damper_force sign), phi relative to the displacement sin(w t); the force on the particles has
  phase phi + 180 deg. Then P = -(A w F1 / 2) sin(phi), a check printed as power_from_harmonic.
  Complex effective mass M = F_on_particles / a_box = F1 e^(i phi) / (w^2 A): Re M is the mass that
  moves with the box, Im M < 0 dissipates (P = -w^3 A^2 Im M / 2).
Statistics: one value per period over the last PERIODS periods; mean, sample std (ddof=1) and
standard error; the harmonic amplitude/phase are those of the mean complex coefficient.

usage: power_force.py FORCE_LOG [--frequency 20] [--amplitude 0.004] [--dt 1e-6] [--periods 5]
                      [--particle-mass KG] [--prefix KEY_PREFIX]
       --particle-mass: total mass, prints m g for the check mean(F_z) = -m g
"""
import argparse

import numpy as np


def load_log(path):
    rows = np.loadtxt(path, comments="#", ndmin=2)
    steps = rows[:, 0].astype(np.int64)
    return steps, rows[:, 1], rows[:, 2], rows[:, 3], rows[:, 4]


def analyse(steps, force_x, force_z, power_in, frequency, amplitude, dt, periods):
    window = int(steps[1] - steps[0])  # steps averaged into each row
    if np.any(np.diff(steps) != window):
        raise ValueError("rows are not equally spaced")
    steps_per_period = round(1.0 / (frequency * dt))
    if steps_per_period % window:
        raise ValueError("a period (%d steps) is not a whole number of rows" % steps_per_period)
    rows_per_period = steps_per_period // window
    last_period = int(steps[-1]) // steps_per_period
    if last_period < periods:
        raise ValueError("log holds %d whole periods, %d asked" % (last_period, periods))
    omega = 2.0 * np.pi * frequency
    # a row averages steps step-window+1..step: its centre, and the attenuation of a harmonic
    # averaged over that window (discrete boxcar: sin(N w dt/2) / (N sin(w dt/2)))
    centre_time = (steps - 0.5 * (window - 1)) * dt
    attenuation = np.sin(0.5 * window * omega * dt) / (window * np.sin(0.5 * omega * dt))

    per_period = {"power": [], "power_from_force": [], "coefficient": [], "mean_fx": [], "mean_fz": []}
    for k in range(last_period - periods, last_period):
        rows = (steps > k * steps_per_period) & (steps <= (k + 1) * steps_per_period)
        assert rows.sum() == rows_per_period
        t, fx = centre_time[rows], force_x[rows]
        # F ~ a sin + b cos: a = (2/N) sum F sin, b = (2/N) sum F cos over one period; a + i b
        coefficient = 2.0 * np.mean(fx * (np.sin(omega * t) + 1j * np.cos(omega * t))) / attenuation
        per_period["coefficient"].append(coefficient)
        per_period["power"].append(np.mean(power_in[rows]))
        per_period["power_from_force"].append(np.mean(-fx * amplitude * omega * np.cos(omega * t)))
        per_period["mean_fx"].append(np.mean(fx))
        per_period["mean_fz"].append(np.mean(force_z[rows]))
    return {key: np.array(v) for key, v in per_period.items()}, omega


def stats(values):
    std = np.std(values, ddof=1)
    return np.mean(values), std, std / np.sqrt(len(values))


def main():
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("force_log")
    parser.add_argument("--frequency", type=float, default=20.0, help="Hz")
    parser.add_argument("--amplitude", type=float, default=0.004, help="m")
    parser.add_argument("--dt", type=float, default=1e-6, help="s")
    parser.add_argument("--periods", type=int, default=5)
    parser.add_argument("--particle-mass", type=float, help="kg, total")
    parser.add_argument("--prefix", default="", help="put before every key")
    args = parser.parse_args()
    if args.periods < 2:
        parser.error("--periods must be >= 2 for a scatter")

    steps, fx, _, fz, power_in = load_log(args.force_log)
    per, omega = analyse(steps, fx, fz, power_in, args.frequency, args.amplitude, args.dt, args.periods)
    out = []

    def line(key, value, unit, note=""):
        out.append("%s%s = %.6g  # %s%s" % (args.prefix, key, value, unit, ("; " + note) if note else ""))

    p_mean, p_std, p_err = stats(per["power"])
    line("dissipated_power", p_mean, "W", "mean over the last %d periods" % args.periods)
    line("dissipated_power_std", p_std, "W", "sample std of the per-period means")
    line("dissipated_power_stderr", p_err, "W")
    out.append(args.prefix + "dissipated_power_per_period = %s  # W" %
               " ".join("%.6g" % v for v in per["power"]))
    line("power_from_sampled_force", np.mean(per["power_from_force"]), "W",
         "check: from the row-averaged force times v_box at the row centre")

    mean_coefficient = np.mean(per["coefficient"])
    amplitude_f1 = np.abs(mean_coefficient)
    phase_f1 = np.angle(mean_coefficient)
    amplitudes = np.abs(per["coefficient"])
    # per-period phase scatter about the mean phase, wrapped to (-pi, pi]
    phase_dev = np.angle(per["coefficient"] / mean_coefficient)
    line("force_amplitude", amplitude_f1, "N", "first harmonic of F_x on the box, mean complex coefficient")
    line("force_amplitude_std", np.std(amplitudes, ddof=1), "N", "per-period amplitudes")
    out.append(args.prefix + "force_amplitude_per_period = %s  # N" %
               " ".join("%.6g" % v for v in amplitudes))
    line("force_phase", np.degrees(phase_f1), "deg", "F on the box relative to x_box = A sin(w t)")
    line("force_phase_rad", phase_f1, "rad")
    line("force_phase_std", np.degrees(np.std(phase_dev, ddof=1)), "deg", "per-period phases")
    out.append(args.prefix + "force_phase_per_period = %s  # deg" %
               " ".join("%.4g" % np.degrees(phase_f1 + d) for d in phase_dev))
    line("power_from_harmonic", -0.5 * args.amplitude * omega * amplitude_f1 * np.sin(phase_f1), "W",
         "check: -(A w F1 / 2) sin(phi) must equal dissipated_power")
    effective_mass = mean_coefficient / (omega**2 * args.amplitude)
    line("effective_mass_real", effective_mass.real, "kg", "Re(F_on_particles / a_box)")
    line("effective_mass_imag", effective_mass.imag, "kg", "Im(F_on_particles / a_box), < 0 dissipates")
    line("mean_force_x", np.mean(per["mean_fx"]), "N", "check: ~0 in a periodic state")
    line("mean_force_z", np.mean(per["mean_fz"]), "N", "check: -(particle weight) in a periodic state")
    if args.particle_mass:
        line("particle_weight", args.particle_mass * 9.81, "N", "m g, the magnitude mean_force_z must match")
    print("\n".join(out))


if __name__ == "__main__":
    main()
