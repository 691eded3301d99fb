// Exact event-driven reference model of the single-particle impact damper (Masri & Caughey 1966),
// the outside reference against which the DEM + structure coupling is tested. Deliberately shares
// no code with pdsim: the primary follows the closed-form forced damped oscillator between events,
// the ball flies at constant velocity, impact times come from a first-root search that a bound on
// the gap's derivatives makes unable to miss a grazing contact, and impacts follow Newton's law.
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <complex>
#include <cstddef>
#include <limits>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

namespace pdsim::reference {

// Primary M x'' + C x' + K x = F0 sin(2 pi f t) + impacts; ball: a point mass in a slot of the
// primary with no gravity and no friction.
struct ImpactDamperParams {
  double M = 0;          // primary mass, kg
  double K = 0;          // primary stiffness, N/m
  double C = 0;          // primary viscous damping, N s/m (underdamped: C < 2 sqrt(K M))
  double m = 0;          // ball mass, kg (0: a tracer that never moves the primary)
  double e = 1;          // coefficient of restitution at the walls, 0..1
  double clearance = 0;  // free travel d of the ball centre, m: xb - x stays in [-d/2, d/2]
  double F0 = 0;         // force amplitude on the primary, N
  double frequency = 0;  // forcing frequency f, Hz
};

// Absolute positions (m) and velocities (m/s) at time t (s).
struct ImpactDamperState {
  double t = 0, x = 0, v = 0, xb = 0, vb = 0;
};

struct ImpactDamperTrace {
  std::vector<double> t, x, v, xb, vb;  // sampled every dt_sample from the start time
  std::vector<double> impact_times;     // s, every impact with a non-zero approach speed
  double dissipated = 0;                // J lost in impacts
  std::size_t sticking_phases = 0;      // chattering sequences ended by riding on a wall
  ImpactDamperState end;                // state at t_end, to continue a run
};

// Velocities just after an impact (relative velocity reversed and scaled by e, momentum kept).
struct ImpactVelocities {
  double v = 0, vb = 0;  // primary, ball; m/s
};

inline ImpactVelocities impact_velocities(double M, double m, double e, double v, double vb) {
  const double momentum = m * vb + M * v;
  const double approach = vb - v;
  return {(momentum + m * e * approach) / (m + M), (momentum - M * e * approach) / (m + M)};
}

namespace detail {

using Complex = std::complex<double>;
constexpr double kTwoPi = 6.28318530717958647692;
constexpr double kEps = std::numeric_limits<double>::epsilon();

inline void check_params(const ImpactDamperParams& p) {
  auto require = [](bool ok, const char* what) {
    if (!ok) throw std::invalid_argument(std::string("impact damper reference: ") + what);
  };
  require(p.M > 0 && p.K > 0, "M and K must be > 0");
  require(p.C >= 0 && p.C * p.C < 4 * p.K * p.M, "C must be in [0, 2 sqrt(K M)) (underdamped)");
  require(p.m >= 0, "m must be >= 0");
  require(p.e >= 0 && p.e <= 1, "e must be in [0, 1]");
  require(p.clearance > 0, "clearance must be > 0");
  require(p.frequency >= 0, "frequency must be >= 0");
}

// Closed-form motion of mass x'' + C x' + K x = F0 sin(Omega t) from (t0, x0, v0):
// x^(k)(t) = Re(h lambda^k e^{lambda (t - t0)}) + Re(q (i Omega)^k e^{i Omega t}),
// lambda = -C/(2 mass) + i omega_d, q = -i F0 / (K - mass Omega^2 + i C Omega). The forcing phase
// is advanced from t0 so that Omega t, large after many periods, is rounded once per segment
// (evaluating e^{i Omega t} directly jitters x by |v| ulp(Omega t) / Omega, ~1e-15 m at 180 s,
// which is the whole gap in a chattering sequence).
class Oscillator {
 public:
  Oscillator(double mass, const ImpactDamperParams& p, double t0, double x0, double v0)
      : t0_(t0), omega_(kTwoPi * p.frequency) {
    const double decay_rate = p.C / (2 * mass);  // 1/s
    const double omega_d = std::sqrt(p.K / mass - decay_rate * decay_rate);
    lambda_ = Complex(-decay_rate, omega_d);
    const Complex dynamic_stiffness(p.K - mass * omega_ * omega_, p.C * omega_);
    if (p.F0 != 0 && std::abs(dynamic_stiffness) == 0)
      throw std::invalid_argument("impact damper reference: undamped forcing at resonance");
    const Complex forced = p.F0 == 0 ? Complex(0) : Complex(0, -p.F0) / dynamic_stiffness;
    forced_ = forced * std::exp(Complex(0, omega_ * t0));
    const double z0 = x0 - forced_.real();
    const double dz0 = v0 - (Complex(0, omega_) * forced_).real();
    free_ = Complex(z0, -(dz0 + decay_rate * z0) / omega_d);
  }

  // x, x', x'', ... at t >= t0.
  template <std::size_t N>
  std::array<double, N> derivatives(double t) const {
    Complex free_term = free_ * std::exp(lambda_ * (t - t0_));
    Complex forced_term = forced_ * std::exp(Complex(0, omega_ * (t - t0_)));
    std::array<double, N> d{};
    for (double& dk : d) {
      dk = free_term.real() + forced_term.real();
      free_term *= lambda_;
      forced_term *= Complex(0, omega_);
    }
    return d;
  }

  // Upper bound of |x^(k)(t)| for every t >= t0 (|e^{lambda tau}| <= 1).
  double derivative_bound(int k) const {
    return std::abs(free_) * std::pow(std::abs(lambda_), k) +
           std::abs(forced_) * std::pow(omega_, k);
  }

 private:
  double t0_, omega_;
  Complex lambda_, free_, forced_;  // forced_: q e^{i Omega t0}
};

struct EventSample {
  double t, f, df, ddf;
};

// f(t) = sign x^(order)(t) + offset + slope (t - t0); the event is f reaching <= 0.
// ddf_bound, dddf_bound: sup |f''|, |f'''| over the segment.
struct EventFunction {
  const Oscillator* motion;
  double sign;
  std::size_t order;
  double offset, slope, t0, ddf_bound, dddf_bound;

  EventSample at(double t) const {
    const auto x = motion->derivatives<5>(t);
    return {t, sign * x[order] + offset + slope * (t - t0), sign * x[order + 1] + slope,
            sign * x[order + 2]};
  }
};

// First s > 0 where f + df s - curvature s^2 / 2 (a lower bound of the function) reaches 0.
inline double clear_span(double f, double df, double curvature) {
  f = std::max(f, 0.0);
  if (curvature <= 0) return df >= 0 ? std::numeric_limits<double>::infinity() : f / -df;
  const double root = std::sqrt(df * df + 2 * curvature * f);
  return df >= 0 ? (df + root) / curvature : 2 * f / (root - df);
}

// Impact times are resolved to 1e-14 s relative.
inline double time_tolerance(double t, double t_ref) {
  return 1e-14 * std::max(std::abs(t), t_ref);
}

// Earliest t in (a.t, b.t] with f(t) <= 0. A subinterval is skipped only when the Taylor lower
// bounds from both ends (with f'' bounded through f''') prove f > 0 on it, so a dip below zero
// between samples (grazing) cannot be missed; otherwise it is bisected, left half first.
inline std::optional<double> first_crossing(const EventFunction& fn, const EventSample& a,
                                            const EventSample& b, double t_ref) {
  const double width = b.t - a.t;
  const double curvature =
      std::min(fn.ddf_bound, std::max(0.0, 0.5 * (-a.ddf - b.ddf + fn.dddf_bound * width)));
  const double clear_from_a = clear_span(a.f, a.df, curvature);
  if (clear_from_a >= width) return std::nullopt;
  if (b.f > 0 && clear_from_a + clear_span(b.f, -b.df, curvature) > width) return std::nullopt;
  if (width <= time_tolerance(b.t, t_ref)) {
    if (b.f <= 0) return b.t;
    return std::nullopt;
  }
  const EventSample mid = fn.at(a.t + 0.5 * width);
  if (auto t = first_crossing(fn, a, mid, t_ref)) return t;
  if (mid.f <= 0) return mid.t;
  return first_crossing(fn, mid, b, t_ref);
}

}  // namespace detail

// Advances from `start` to t_end (s), sampling every dt_sample (s) from start.t. A chattering
// sequence whose rebound speed falls below 1e-6 d omega_n while the wall pushes the ball is closed
// by one plastic impact and the ball rides on the wall (primary mass M + m) until the wall would
// pull it; the energy this truncation ignores is below (1e-6 d omega_n)^2 m / 2.
inline ImpactDamperTrace simulate_impact_damper(const ImpactDamperParams& p,
                                                ImpactDamperState start, double t_end,
                                                double dt_sample) {
  using detail::EventFunction;
  using detail::EventSample;
  using detail::Oscillator;
  detail::check_params(p);
  if (!(dt_sample > 0) || !(t_end >= start.t))
    throw std::invalid_argument("impact damper reference: need dt_sample > 0, t_end >= start.t");
  const double half = 0.5 * p.clearance;
  if (std::abs(start.xb - start.x) > half * (1 + 1e-12))
    throw std::invalid_argument("impact damper reference: the ball starts outside the slot");

  const double omega_n = std::sqrt(p.K / p.M);
  const double t_ref = detail::kTwoPi / omega_n;
  const double macro_step =
      std::min(t_ref, p.frequency > 0 ? 1 / p.frequency : t_ref) / 32;  // s, bisection start
  const double rebound_floor = 1e-6 * p.clearance * omega_n;            // m/s
  const double reduced_mass = p.m * p.M / (p.m + p.M);                  // kg
  const double omega_f = detail::kTwoPi * p.frequency;

  ImpactDamperTrace trace;
  ImpactDamperState s = start;
  int stuck_wall = 0;  // +1: riding on the upper wall (xb = x + d/2), -1: the lower one, 0: flying

  // Acceleration of primary + ball riding together; the wall pushes the ball while
  // wall * acceleration <= 0 (to round-off).
  auto wall_pushes = [&](int wall) {
    const double force = p.F0 * std::sin(omega_f * s.t) - p.C * s.v - p.K * s.x;
    const double noise =
        16 * detail::kEps * (std::abs(p.F0) + std::abs(p.C * s.v) + std::abs(p.K * s.x));
    return -wall * force > -noise;
  };
  auto resolve_contact = [&](int wall) {
    s.xb = s.x + wall * half;
    const double closing = wall * (s.vb - s.v);  // m/s, > 0: the ball moves into the wall
    const double approach = std::max(0.0, closing);
    if (approach > 0) trace.impact_times.push_back(s.t);
    const double rebound = approach > 0 ? p.e * approach : -closing;  // m/s away from the wall
    if (rebound < rebound_floor) {
      const double common_v = (p.m * s.vb + p.M * s.v) / (p.m + p.M);
      const ImpactDamperState before = s;
      s.v = s.vb = common_v;
      if (wall_pushes(wall)) {
        trace.dissipated += 0.5 * reduced_mass * closing * closing;
        stuck_wall = wall;
        ++trace.sticking_phases;
        return;
      }
      s = before;
    }
    if (approach == 0) return;
    const ImpactVelocities after = impact_velocities(p.M, p.m, p.e, s.v, s.vb);
    s.v = after.v;
    s.vb = after.vb;
    trace.dissipated += 0.5 * (1 - p.e * p.e) * reduced_mass * approach * approach;
  };
  auto gap = [&](int wall) { return half - wall * (s.xb - s.x); };
  const double start_noise = 16 * detail::kEps * (std::abs(s.x) + std::abs(s.xb) + half);
  for (int wall : {1, -1})
    if (stuck_wall == 0 && gap(wall) <= start_noise) resolve_contact(wall);

  std::size_t next_sample = 0;
  auto sample_time = [&] { return start.t + static_cast<double>(next_sample) * dt_sample; };
  for (std::size_t events = 0;; ++events) {
    if (events > 100000000)
      throw std::runtime_error("impact damper reference: more than 1e8 events");
    const Oscillator motion(stuck_wall != 0 ? p.M + p.m : p.M, p, s.t, s.x, s.v);
    std::vector<EventFunction> events_fn;
    std::vector<int> event_wall;
    if (stuck_wall != 0) {
      // Leaves the wall when wall * x'' turns > 0: f = -wall x''.
      const double noise = 16 * detail::kEps * motion.derivative_bound(2);
      events_fn.push_back({&motion, -static_cast<double>(stuck_wall), 2, noise, 0, s.t,
                           motion.derivative_bound(4), motion.derivative_bound(5)});
      event_wall.push_back(stuck_wall);
    } else {
      // Gap to a wall: d/2 - wall (xb(t) - x(t)), shifted by its round-off level.
      const double noise =
          16 * detail::kEps * (2 * motion.derivative_bound(0) + std::abs(s.xb) + 2 * half);
      for (int wall : {1, -1}) {
        events_fn.push_back({&motion, static_cast<double>(wall), 0, half - wall * s.xb + noise,
                             -wall * s.vb, s.t, motion.derivative_bound(2),
                             motion.derivative_bound(3)});
        event_wall.push_back(wall);
      }
    }

    std::optional<double> event_time;
    int hit = 0;
    std::vector<EventSample> left(events_fn.size());
    for (std::size_t i = 0; i < events_fn.size(); ++i) left[i] = events_fn[i].at(s.t);
    for (double a = s.t; a < t_end && !event_time;) {
      const double b = std::min(a + macro_step, t_end);
      for (std::size_t i = 0; i < events_fn.size(); ++i) {
        const EventSample right = events_fn[i].at(b);
        const auto t = detail::first_crossing(events_fn[i], left[i], right, t_ref);
        if (t && (!event_time || *t < *event_time)) {
          event_time = t;
          hit = event_wall[i];
        }
        left[i] = right;
      }
      a = b;
    }

    const double t_stop = event_time ? *event_time : t_end;
    const ImpactDamperState segment_start = s;
    auto state_at = [&](double t) {
      const auto x = motion.derivatives<2>(t);
      if (stuck_wall != 0) return ImpactDamperState{t, x[0], x[1], x[0] + stuck_wall * half, x[1]};
      return ImpactDamperState{t, x[0], x[1],
                               segment_start.xb + segment_start.vb * (t - segment_start.t),
                               segment_start.vb};
    };
    for (double ts = sample_time(); event_time ? ts < t_stop : ts <= t_end + 1e-9 * dt_sample;
         ts = sample_time()) {
      const ImpactDamperState at = state_at(ts);
      trace.t.push_back(ts);
      trace.x.push_back(at.x);
      trace.v.push_back(at.v);
      trace.xb.push_back(at.xb);
      trace.vb.push_back(at.vb);
      ++next_sample;
    }
    s = state_at(t_stop);
    if (!event_time) break;
    if (stuck_wall != 0) {
      stuck_wall = 0;  // separation: the ball leaves the wall with the primary's velocity
    } else {
      resolve_contact(hit);
    }
  }
  trace.end = s;
  return trace;
}

// Free decay: primary released from rest at x0 (m), ball at rest at the slot centre, no force.
inline ImpactDamperTrace simulate_free_decay(ImpactDamperParams p, double x0, double t_end,
                                             double dt_sample) {
  p.F0 = 0;
  return simulate_impact_damper(p, {0, x0, 0, x0, 0}, t_end, dt_sample);
}

// Amplitude of the first harmonic at f (Hz) of x(t) over the whole periods after t_from
// (rectangle rule: exact for uniform samples whose step divides the period).
inline double first_harmonic_amplitude(const std::vector<double>& t, const std::vector<double>& x,
                                       double f, double t_from) {
  if (t.size() != x.size() || t.empty() || !(f > 0))
    throw std::invalid_argument("first_harmonic_amplitude: need matching samples and f > 0");
  const double period = 1 / f;
  const double periods = std::floor((t.back() - t_from) / period * (1 + 1e-12));
  if (periods < 1) throw std::invalid_argument("first_harmonic_amplitude: less than one period");
  const double t_to = t_from + periods * period;
  const double slack = 1e-9 * period;
  double cos_sum = 0, sin_sum = 0;
  std::size_t count = 0;
  for (std::size_t i = 0; i < t.size(); ++i) {
    if (t[i] < t_from - slack || t[i] >= t_to - slack) continue;
    const double phase = detail::kTwoPi * f * t[i];
    cos_sum += x[i] * std::cos(phase);
    sin_sum += x[i] * std::sin(phase);
    ++count;
  }
  return 2 * std::hypot(cos_sum, sin_sum) / static_cast<double>(count);
}

// Steady motion with two impacts per cycle, equally spaced (Masri & Caughey, J. Appl. Mech. 33,
// 1966; with primary damping as in Masri, J. Acoust. Soc. Am. 47, 1970), derived here afresh from
// their assumptions: x(t + T/2) = -x(t), the ball hits the upper wall at t1, the lower at t1 + T/2.
struct SymmetricTwoImpactMotion {
  ImpactDamperState after_impact;  // just after the upper-wall impact, t in [0, T)
  double v_before = 0;             // m/s, primary velocity just before that impact
  double first_harmonic = 0;       // m, first-harmonic amplitude of x(t)
  bool admissible = false;  // ball approaches the walls and touches none between the two impacts
};

// The candidate solutions (0, 1 or 2). Unknowns y = (X, v+, v-, W): primary displacement at the
// impact, velocity after and before it, ball velocity after it. With Phi the free-oscillator
// transition over T/2 and z = x - x_particular: flight  W T/2 = -(2 X + d);  Newton
// W - v+ = e (W + v-);  momentum M (v+ - v-) = -2 m W;  symmetry  z(t1 + T/2) = -(z(t1) with v-).
// Four rows give y affine in (cos, sin) of the impact phase; the fifth gives
// cos_part cos(phase) + sin_part sin(phase) = constant, solved in closed form.
inline std::vector<SymmetricTwoImpactMotion> symmetric_two_impact_motions(
    const ImpactDamperParams& p) {
  using detail::Complex;
  detail::check_params(p);
  if (!(p.frequency > 0) || p.F0 == 0)
    throw std::invalid_argument("symmetric_two_impact_motions: needs harmonic forcing");
  const double omega = detail::kTwoPi * p.frequency;
  const double half_period = 0.5 / p.frequency;
  const double decay_rate = p.C / (2 * p.M);
  const double omega_d = std::sqrt(p.K / p.M - decay_rate * decay_rate);
  // Phi = e^{-a tau} [[c + a s, s], [-(K/M) s, c - a s]], c = cos(omega_d tau), s = sin/omega_d.
  const double damping_factor = std::exp(-decay_rate * half_period);
  const double c = std::cos(omega_d * half_period), sn = std::sin(omega_d * half_period) / omega_d;
  const double phi11 = damping_factor * (c + decay_rate * sn), phi12 = damping_factor * sn;
  const double phi21 = -damping_factor * p.K / p.M * sn;
  const double phi22 = damping_factor * (c - decay_rate * sn);
  // Particular solution Re(q e^{i Omega t}): at phase psi, xp = Re(q) cos - Im(q) sin,
  // vp = -Omega Im(q) cos - Omega Re(q) sin.
  const Complex q = Complex(0, -p.F0) / Complex(p.K - p.M * omega * omega, p.C * omega);
  const std::array<double, 2> xp = {q.real(), -q.imag()};  // (cos, sin) parts
  const std::array<double, 2> vp = {-omega * q.imag(), -omega * q.real()};

  using Row = std::array<double, 4>;
  std::array<Row, 4> rows = {Row{2, 0, 0, half_period}, Row{0, -1, -p.e, 1 - p.e},
                             Row{0, 1, -1, 2 * p.m / p.M}, Row{phi11 + 1, phi12, 0, 0}};
  // Right-hand sides: column 0 constant, 1 the cos(phase) part, 2 the sin(phase) part.
  std::array<std::array<double, 3>, 4> rhs = {};
  rhs[0][0] = -p.clearance;
  for (std::size_t k = 0; k < 2; ++k) rhs[3][k + 1] = (phi11 + 1) * xp[k] + phi12 * vp[k];
  for (std::size_t col = 0; col < 4; ++col) {  // Gaussian elimination, partial pivoting
    std::size_t pivot = col;
    for (std::size_t r = col + 1; r < 4; ++r)
      if (std::abs(rows[r][col]) > std::abs(rows[pivot][col])) pivot = r;
    std::swap(rows[col], rows[pivot]);
    std::swap(rhs[col], rhs[pivot]);
    if (std::abs(rows[col][col]) < 1e-300)
      throw std::runtime_error("symmetric_two_impact_motions: singular system");
    for (std::size_t r = 0; r < 4; ++r) {
      if (r == col) continue;
      const double factor = rows[r][col] / rows[col][col];
      for (std::size_t k = 0; k < 4; ++k) rows[r][k] -= factor * rows[col][k];
      for (std::size_t k = 0; k < 3; ++k) rhs[r][k] -= factor * rhs[col][k];
    }
  }
  std::array<std::array<double, 4>, 3> y = {};  // y = y[0] + cos y[1] + sin y[2]
  for (std::size_t r = 0; r < 4; ++r)
    for (std::size_t k = 0; k < 3; ++k) y[k][r] = rhs[r][k] / rows[r][r];
  // Fifth row: phi21 X + phi22 v+ + v- - phi21 xp - (phi22 + 1) vp = 0.
  auto fifth = [&](std::size_t k) { return phi21 * y[k][0] + phi22 * y[k][1] + y[k][2]; };
  const double cos_part = fifth(1) - phi21 * xp[0] - (phi22 + 1) * vp[0];
  const double sin_part = fifth(2) - phi21 * xp[1] - (phi22 + 1) * vp[1];
  const double constant = -fifth(0);
  const double magnitude = std::hypot(cos_part, sin_part);
  std::vector<SymmetricTwoImpactMotion> motions;
  if (!(magnitude > 0) || std::abs(constant) > magnitude) return motions;  // no such motion
  const double centre = std::atan2(sin_part, cos_part), spread = std::acos(constant / magnitude);
  for (double phase : {centre + spread, centre - spread}) {
    phase = std::fmod(phase, detail::kTwoPi);
    if (phase < 0) phase += detail::kTwoPi;
    const double cs = std::cos(phase), ss = std::sin(phase);
    std::array<double, 4> sol{};
    for (std::size_t r = 0; r < 4; ++r) sol[r] = y[0][r] + cs * y[1][r] + ss * y[2][r];
    SymmetricTwoImpactMotion motion;
    const double t1 = phase / omega;
    motion.after_impact = {t1, sol[0], sol[1], sol[0] + 0.5 * p.clearance, sol[3]};
    motion.v_before = sol[2];
    // First harmonic: q from the particular part plus, by the half-period antisymmetry,
    // (2/T) e^{-i Omega t1} [h I(lambda) + conj(h) I(conj(lambda))] from z = Re(h e^{lambda tau}),
    // I(mu) = (e^{(mu - i Omega) T/2} - 1) / (mu - i Omega).
    const double xp1 = xp[0] * cs + xp[1] * ss, vp1 = vp[0] * cs + vp[1] * ss;
    const double z0 = sol[0] - xp1, dz0 = sol[1] - vp1;
    const Complex h(z0, -(dz0 + decay_rate * z0) / omega_d);
    const Complex lambda(-decay_rate, omega_d);
    auto integral = [&](Complex mu) {
      const Complex k = mu - Complex(0, omega);
      return (std::exp(k * half_period) - 1.0) / k;
    };
    const Complex harmonic =
        q + 2 * p.frequency * std::exp(Complex(0, -phase)) *
                (h * integral(lambda) + std::conj(h) * integral(std::conj(lambda)));
    motion.first_harmonic = std::abs(harmonic);
    const bool approaches = -sol[3] - sol[2] > 0;  // ball (velocity -W) closes on the upper wall
    const double just_before_next = t1 + half_period * (1 - 1e-9);
    motion.admissible =
        approaches && simulate_impact_damper(p, motion.after_impact, just_before_next, half_period)
                          .impact_times.empty();
    motions.push_back(motion);
  }
  return motions;
}

}  // namespace pdsim::reference
