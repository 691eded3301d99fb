// Structural models against closed-form beam and oscillator results.
#include "io/deck.hpp"
#include "src/scene.hpp"
#include "structure/structure.hpp"
#include "tests/support/validation_row.hpp"

#include <doctest/doctest.h>

#include <Eigen/Eigenvalues>
#include <array>
#include <cmath>
#include <string>
#include <vector>

namespace pdsim {
namespace {

// Aluminium strip 0.5 m x 30 mm x 5 mm (examples/beam_damper.toml), bending across the 5 mm.
Deck beam_deck(Support start, Support end, int elements) {
  Deck deck;
  deck.path = "inline.toml";
  StructureSpec& s = deck.structure;
  s.kind = StructureKind::beam;
  BeamSpec& b = s.beam;
  b.length = 0.5;
  b.elements = elements;
  b.young = 7.0e10;
  b.density = 2700.0;
  b.poisson = 0.33;
  const double width = 0.03, height = 0.005;
  b.area = width * height;
  b.inertia = width * height * height * height / 12;
  b.start = start;
  b.end = end;
  return deck;
}

Deck sdof_deck() {
  Deck deck;
  deck.path = "inline.toml";
  deck.structure.kind = StructureKind::sdof;
  deck.structure.mass = 2.37;  // Saeki's (2002) primary system, as examples/saeki_250.toml
  deck.structure.stiffness = 21500.0;
  deck.structure.damping = 1.0;
  deck.dampers.resize(2);
  return deck;
}

DamperSpec damper_at_node(int node) {
  DamperSpec d;
  d.attach_node = node;
  return d;
}

DamperSpec damper_at_x(double x) {
  DamperSpec d;
  d.attach_x = x;
  return d;
}

// sqrt(EI / (rho A)), m^2/s.
double bending_wave_constant(const BeamSpec& b) {
  return std::sqrt(b.young * b.inertia / (b.density * b.area));
}

double relative_error(double value, double reference) {
  return (value - reference) / reference;
}

// Free-mode shapes of (K, M), mass-normalised, and circular frequencies (rad/s).
struct Modes {
  Eigen::MatrixXd shapes;
  Eigen::VectorXd omega;
};
Modes modes_of(const LinearStructure& s) {
  Eigen::GeneralizedSelfAdjointEigenSolver<Eigen::MatrixXd> eigen(s.stiffness, s.mass);
  return {eigen.eigenvectors(), eigen.eigenvalues().cwiseSqrt()};
}

// Cantilever eigenvalues lambda_n L (Blevins, Formulas for Natural Frequency and Mode Shape,
// table 8-1) and the FE errors of 8 Hermite elements with consistent mass (from above, O(h^4)).
constexpr std::array<double, 4> kCantileverLambda = {1.87510407, 4.69409113, 7.85475744,
                                                     10.99554073};
constexpr std::array<double, 4> kEightElementError = {2e-6, 8e-5, 6e-4, 2e-3};

TEST_CASE("cantilever frequencies converge from above at O(h^4)") {
  for (const int elements : {8, 16}) {
    const Deck deck = beam_deck(Support::clamped, Support::free, elements);
    const std::vector<double> hz = natural_frequencies(build_structure(deck));
    REQUIRE(hz.size() == 2u * elements);
    const double l = deck.structure.beam.length;
    for (std::size_t n = 0; n < 4; ++n) {
      // f_n = lambda_n^2 / (2 pi L^2) sqrt(EI / (rho A)) (Blevins table 8-1).
      const double exact = kCantileverLambda[n] * kCantileverLambda[n] / (2 * kPi * l * l) *
                           bending_wave_constant(deck.structure.beam);
      const double bound = 1.5 * kEightElementError[n] * (elements == 8 ? 1.0 : 1.0 / 16);
      CAPTURE(elements);
      CAPTURE(n);
      const double error = relative_error(hz[n], exact);
      CHECK(error > 0);
      CHECK(error < bound);
      if (elements == 16)
        validation_row("cantilever mode " + std::to_string(n + 1) + ", 16 elements",
                       "Euler-Bernoulli, Blevins table 8-1", exact, hz[n], bound, "Hz");
    }
  }
}

TEST_CASE("simply supported beam frequencies converge from above at O(h^4)") {
  std::vector<double> error_8, error_16;
  for (const int elements : {8, 16}) {
    const Deck deck = beam_deck(Support::pinned, Support::pinned, elements);
    const std::vector<double> hz = natural_frequencies(build_structure(deck));
    REQUIRE(hz.size() == 2u * elements);  // two supports remove one DOF each
    const double l = deck.structure.beam.length;
    for (int n = 1; n <= 4; ++n) {
      // f_n = n^2 pi / (2 L^2) sqrt(EI / (rho A)) (Blevins table 8-1, pinned-pinned).
      const double exact = n * n * kPi / (2 * l * l) * bending_wave_constant(deck.structure.beam);
      const double error = relative_error(hz[static_cast<std::size_t>(n - 1)], exact);
      (elements == 8 ? error_8 : error_16).push_back(error);
    }
  }
  for (std::size_t i = 0; i < 4; ++i) {
    CAPTURE(i);
    CHECK(error_16[i] > 0);
    // Halving the element length divides an O(h^4) error by 16 (less once the mode is
    // resolved by few elements: mode 4 has a half wavelength of 2 elements at 8 elements).
    CHECK(error_8[i] / error_16[i] > (i < 2 ? 15.5 : 14.0));
    CHECK(error_8[i] / error_16[i] < 16.5);
  }
}

TEST_CASE("cantilever static tip load: deflection P L^3 / 3EI, slope P L^2 / 2EI") {
  const Deck deck = beam_deck(Support::clamped, Support::free, 8);
  const LinearStructure s = build_structure(deck);
  const double load = 3.0;  // N at the tip (no damper: force_shape is the last node)
  const Eigen::VectorXd q = s.stiffness.ldlt().solve(load * s.force_shape);
  const BeamSpec& b = deck.structure.beam;
  const double ei = b.young * b.inertia, l = b.length;
  // Hermite cubics contain the exact static solution, so nodal values are exact.
  CHECK(s.response * q == doctest::Approx(load * l * l * l / (3 * ei)).epsilon(1e-12));
  CHECK(q(s.size() - 1) == doctest::Approx(load * l * l / (2 * ei)).epsilon(1e-12));
}

TEST_CASE("base acceleration loads a cantilever like a uniform load: tip w L^4 / 8EI") {
  for (const int modes : {0, 16}) {
    Deck deck = beam_deck(Support::clamped, Support::free, 8);
    deck.structure.modes = modes;
    const LinearStructure s = build_structure(deck);
    const double acceleration = 9.81;  // m/s^2 of the support, along `direction`
    const Eigen::VectorXd load = -s.mass * s.base_influence * acceleration;
    const Eigen::VectorXd q = s.stiffness.ldlt().solve(load);
    const BeamSpec& b = deck.structure.beam;
    const double line_load = -b.density * b.area * acceleration;  // N/m, d'Alembert
    // Uniform load on a cantilever (Roark, table 8.1 case 2a); consistent loads make the
    // Hermite nodal values exact.
    CAPTURE(modes);
    CHECK(s.response * q ==
          doctest::Approx(line_load * std::pow(b.length, 4) / (8 * b.young * b.inertia))
              .epsilon(1e-10));
  }
}

TEST_CASE("attachments snap to nodes and their maps give the beam's kinematics") {
  Deck deck = beam_deck(Support::clamped, Support::free, 8);  // nodes every 62.5 mm
  deck.dampers = {damper_at_x(0.33), damper_at_node(8)};
  const BeamSpec& b = deck.structure.beam;
  const double ei = b.young * b.inertia, l = b.length;
  const double a = 0.3125;  // node 5, the nearest to x = 0.33
  const double load = 2.0;  // N at the first damper (force_shape)

  for (const int modes : {0, 16}) {
    deck.structure.modes = modes;  // the full-rank modal basis must map the same kinematics
    const LinearStructure s = build_structure(deck);
    REQUIRE(s.attachments.size() == 2u);
    CHECK(s.attachments[0].node == 5);
    CHECK(s.attachments[0].x == doctest::Approx(a));
    CHECK(s.attachments[1].node == 8);
    const Eigen::VectorXd q = s.stiffness.ldlt().solve(load * s.force_shape);
    const Eigen::VectorXd w = s.attachment_translation * q, theta = s.attachment_rotation * q;
    CAPTURE(modes);
    // Cantilever with a load P at a (Roark, table 8.1 case 1a): w(a) = P a^3 / 3EI, beyond a
    // the beam is straight with slope P a^2 / 2EI, so w(L) = P a^2 (3L - a) / 6EI.
    CHECK(w(0) == doctest::Approx(load * a * a * a / (3 * ei)).epsilon(1e-9));
    CHECK(w(1) == doctest::Approx(load * a * a * (3 * l - a) / (6 * ei)).epsilon(1e-9));
    CHECK(theta(0) == doctest::Approx(load * a * a / (2 * ei)).epsilon(1e-9));
    CHECK(theta(1) == doctest::Approx(load * a * a / (2 * ei)).epsilon(1e-9));
    CHECK(s.response * q == doctest::Approx(w(0)).epsilon(1e-12));
  }
}

TEST_CASE("attachment outside the beam is an input error naming the key") {
  Deck deck = beam_deck(Support::clamped, Support::free, 8);
  deck.dampers = {damper_at_node(3), damper_at_x(0.6)};
  CHECK_THROWS_WITH_AS(build_structure(deck), doctest::Contains("'damper[1].attach'"), InputError);
  deck.dampers = {damper_at_node(9)};
  CHECK_THROWS_WITH_AS(build_structure(deck), doctest::Contains("'damper[0].attach'"), InputError);
  deck.dampers = {damper_at_x(-1e-3)};
  CHECK_THROWS_AS(build_structure(deck), InputError);
  deck.dampers = {damper_at_x(0.5)};  // the tip itself is on the beam
  CHECK(build_structure(deck).attachments[0].node == 8);
}

TEST_CASE("Timoshenko: slender beam equals Euler-Bernoulli, stubby beam is lower") {
  Deck deck = beam_deck(Support::clamped, Support::free, 16);  // L / h = 100
  const double euler_bernoulli = natural_frequencies(build_structure(deck))[0];
  deck.structure.beam.timoshenko = true;
  deck.structure.beam.shear_factor = 5.0 / 6.0;
  const double timoshenko = natural_frequencies(build_structure(deck))[0];
  CHECK(timoshenko < euler_bernoulli);
  CHECK(std::abs(relative_error(timoshenko, euler_bernoulli)) < 1e-4);
}

// Steel block 0.1 m long, 30 mm wide, 20 mm deep (L / h = 5): shear and rotary inertia matter.
Deck stubby_deck(Support start, Support end, bool timoshenko, int elements) {
  Deck deck = beam_deck(start, end, elements);
  BeamSpec& b = deck.structure.beam;
  b.length = 0.1;
  b.young = 2.1e11;
  b.density = 7850.0;
  b.poisson = 0.3;
  b.area = 0.03 * 0.02;
  b.inertia = 0.03 * 0.02 * 0.02 * 0.02 / 12;
  b.timoshenko = timoshenko;
  b.shear_factor = 5.0 / 6.0;
  return deck;
}

// Timoshenko beam theory, rho A w_tt = kGA (w'' - psi'), rho I psi_tt = EI psi'' + kGA (w' - psi)
// (Han, Benaroya & Wei 1999, J. Sound Vib. 225(5):935-988): below the cut-off frequency the
// spatial solutions are cosh/sinh(alpha x), cos/sin(beta x) with alpha^2, -beta^2 the roots of
// kGA EI mu^2 + w^2 (kGA rho I + rho A EI) mu + rho A w^2 (rho I w^2 - kGA) = 0.
struct TimoshenkoBeam {
  double ei, kga, rho_a, rho_i, length;

  explicit TimoshenkoBeam(const BeamSpec& b)
      : ei(b.young * b.inertia),
        kga(b.shear_factor * b.young / (2 * (1 + b.poisson)) * b.area),
        rho_a(b.density * b.area),
        rho_i(b.density * b.inertia),
        length(b.length) {}

  // Pinned-pinned, mode n: w = sin(n pi x / L), the lower root of the quadratic in w^2.
  double pinned_pinned_hz(int n) const {
    const double k = n * kPi / length, k2 = k * k;
    const double a = rho_a * rho_i / kga, b = -(rho_a + rho_i * k2 + ei * rho_a * k2 / kga),
                 c = ei * k2 * k2;
    return std::sqrt((-b - std::sqrt(b * b - 4 * a * c)) / (2 * a)) / (2 * kPi);
  }

  // Clamped (w = psi = 0) at x = 0, free (EI psi' = 0, kGA (w' - psi) = 0) at x = L.
  double clamped_free_determinant(double omega) const {
    const double w2 = omega * omega;
    const double a = kga * ei, b = w2 * (kga * rho_i + rho_a * ei),
                 c = rho_a * w2 * (rho_i * w2 - kga);
    const double root = std::sqrt(b * b - 4 * a * c);
    const double alpha = std::sqrt((-b + root) / (2 * a)), beta = std::sqrt((b + root) / (2 * a));
    const double g_alpha = alpha * alpha + rho_a * w2 / kga,
                 g_beta = -beta * beta + rho_a * w2 / kga;
    const double al = alpha * length, bl = beta * length;
    Eigen::Matrix4d bc;
    bc << 1, 0, 1, 0,                           //
        0, g_alpha / alpha, 0, -g_beta / beta,  //
        g_alpha * std::cosh(al), g_alpha * std::sinh(al), g_beta * std::cos(bl),
        g_beta * std::sin(bl),  //
        (alpha - g_alpha / alpha) * std::sinh(al), (alpha - g_alpha / alpha) * std::cosh(al),
        -(beta + g_beta / beta) * std::sin(bl), (beta + g_beta / beta) * std::cos(bl);
    return bc.determinant();
  }

  // First root above omega_start (rad/s): scan, then bisect.
  double clamped_free_first_hz(double omega_start) const {
    double low = omega_start, high = omega_start * 1.001;
    while (std::signbit(clamped_free_determinant(low)) ==
           std::signbit(clamped_free_determinant(high))) {
      low = high;
      high *= 1.001;
    }
    for (int i = 0; i < 100; ++i) {
      const double mid = 0.5 * (low + high);
      if (std::signbit(clamped_free_determinant(mid)) ==
          std::signbit(clamped_free_determinant(low))) {
        low = mid;
      } else {
        high = mid;
      }
    }
    return 0.5 * (low + high) / (2 * kPi);
  }
};

// The Timoshenko element's shear strain is constant per element, so its frequencies converge at
// O(h^2) (unlike Euler-Bernoulli's O(h^4)): compare the Richardson extrapolation of 32 and 64
// elements, (4 f_64 - f_32) / 3, with the theory.
double extrapolated_hz(Support start, Support end, std::size_t mode) {
  const double coarse =
      natural_frequencies(build_structure(stubby_deck(start, end, true, 32)))[mode];
  const double fine = natural_frequencies(build_structure(stubby_deck(start, end, true, 64)))[mode];
  CHECK(fine < coarse);  // Rayleigh-Ritz: from above
  return (4 * fine - coarse) / 3;
}

TEST_CASE("Timoshenko stubby beam matches Timoshenko beam theory") {
  const TimoshenkoBeam theory(
      stubby_deck(Support::pinned, Support::pinned, true, 32).structure.beam);
  const std::vector<double> euler_bernoulli = natural_frequencies(
      build_structure(stubby_deck(Support::pinned, Support::pinned, false, 32)));
  for (int n = 1; n <= 3; ++n) {
    const auto i = static_cast<std::size_t>(n - 1);
    CAPTURE(n);
    const double hz = extrapolated_hz(Support::pinned, Support::pinned, i);
    CHECK(hz < 0.97 * euler_bernoulli[i]);  // shear and rotary inertia lower f by several %
    CHECK(std::abs(relative_error(hz, theory.pinned_pinned_hz(n))) < 1e-6);
  }

  const double cantilever = extrapolated_hz(Support::clamped, Support::free, 0);
  const double cantilever_eb = natural_frequencies(
      build_structure(stubby_deck(Support::clamped, Support::free, false, 32)))[0];
  CHECK(cantilever < cantilever_eb);
  const double exact = theory.clamped_free_first_hz(0.5 * 2 * kPi * cantilever_eb);
  CHECK(std::abs(relative_error(cantilever, exact)) < 1e-6);
}

TEST_CASE("modal reduction keeps the retained frequencies") {
  Deck deck = beam_deck(Support::clamped, Support::free, 8);
  deck.structure.damping_ratio = 0.01;
  const std::vector<double> full = natural_frequencies(build_structure(deck));
  deck.structure.modes = 16;
  const std::vector<double> all_modes = natural_frequencies(build_structure(deck));
  REQUIRE(all_modes.size() == full.size());
  for (std::size_t i = 0; i < full.size(); ++i) {
    CHECK(all_modes[i] == doctest::Approx(full[i]).epsilon(1e-10));
  }
  deck.structure.modes = 4;
  const LinearStructure reduced = build_structure(deck);
  const std::vector<double> four = natural_frequencies(reduced);
  REQUIRE(four.size() == 4u);
  for (std::size_t i = 0; i < 4; ++i) CHECK(four[i] == doctest::Approx(full[i]).epsilon(1e-10));
  CHECK((reduced.mass - Eigen::MatrixXd::Identity(4, 4)).norm() < 1e-12);

  deck.structure.modes = 17;
  CHECK_THROWS_AS(build_structure(deck), InputError);
}

TEST_CASE("reduced base influence gives the cantilever's effective modal masses") {
  Deck deck = beam_deck(Support::clamped, Support::free, 16);
  deck.structure.modes = 3;
  const LinearStructure s = build_structure(deck);
  const BeamSpec& b = deck.structure.beam;
  const double beam_mass = b.density * b.area * b.length;
  // Effective mass of cantilever mode n, Gamma_n^2 with Gamma_n = Phi_n^T M r: for the mode
  // cosh - cos - sigma (sinh - sin), int phi = 2 sigma L / lambda and int phi^2 = L, so
  // m_eff / m = 4 sigma_n^2 / lambda_n^2 (sigma_n from Blevins table 8-1): 0.613, 0.188, 0.065.
  for (std::size_t n = 0; n < 3; ++n) {
    const double lambda = kCantileverLambda[n];
    const double sigma =
        (std::sinh(lambda) - std::sin(lambda)) / (std::cosh(lambda) + std::cos(lambda));
    const auto i = static_cast<Eigen::Index>(n);
    const double effective = s.base_influence(i) * s.base_influence(i) / beam_mass;
    CAPTURE(n);
    CHECK(effective == doctest::Approx(4 * sigma * sigma / (lambda * lambda)).epsilon(1e-4));
  }
}

TEST_CASE("damping: Rayleigh and modal ratios") {
  Deck deck = beam_deck(Support::clamped, Support::free, 8);
  const double alpha = 2.0, beta = 3e-5;
  deck.structure.rayleigh = std::array<double, 2>{alpha, beta};
  const LinearStructure rayleigh = build_structure(deck);
  const Modes modes = modes_of(rayleigh);
  const Eigen::MatrixXd modal_rayleigh = modes.shapes.transpose() * rayleigh.damping * modes.shapes;
  for (Eigen::Index i = 0; i < 4; ++i) {
    const double w = modes.omega(i);
    // zeta_n = alpha / (2 w_n) + beta w_n / 2 (Chopra, Dynamics of Structures, Rayleigh damping).
    CHECK(modal_rayleigh(i, i) / (2 * w) ==
          doctest::Approx(alpha / (2 * w) + beta * w / 2).epsilon(1e-9));
  }

  deck.structure.rayleigh.reset();
  deck.structure.damping_ratio = 0.02;
  const LinearStructure modal = build_structure(deck);
  const Eigen::MatrixXd modal_damping = modes.shapes.transpose() * modal.damping * modes.shapes;
  const Eigen::VectorXd expected = 2 * 0.02 * modes.omega;
  CHECK((modal_damping - Eigen::MatrixXd(expected.asDiagonal())).norm() < 1e-9 * expected.norm());
}

TEST_CASE("sdof model: Saeki's primary system at 15.16 Hz, one attachment per damper") {
  const LinearStructure s = build_structure(sdof_deck());
  REQUIRE(s.size() == 1);
  CHECK(s.damping(0, 0) == 1.0);
  CHECK(natural_frequencies(s)[0] == doctest::Approx(15.16).epsilon(5e-4));
  REQUIRE(s.attachments.size() == 2u);
  CHECK(s.attachments[1].translation_dof == 0);
  CHECK(s.attachments[1].rotation_dof == -1);
  CHECK(s.attachment_translation.rows() == 2);
  CHECK(s.attachment_translation.sum() == 2.0);
  CHECK(s.attachment_rotation.norm() == 0.0);
  CHECK(s.base_influence(0) == 1.0);
  CHECK(s.force_shape(0) == 1.0);
  CHECK(s.response(0) == 1.0);
}

TEST_CASE("no structure is an input error") {
  Deck deck;
  CHECK_THROWS_AS(build_structure(deck), InputError);
}

TEST_CASE("format_modes lists modes with 6 significant digits") {
  const std::vector<double> hz = {15.159057, 1234.56789, 0.000123456789};
  CHECK(format_modes(hz, 2) == "mode 1 15.1591 Hz\nmode 2 1234.57 Hz\n");
  CHECK(format_modes(hz, 0) == "mode 1 15.1591 Hz\nmode 2 1234.57 Hz\nmode 3 0.000123457 Hz\n");
  CHECK(format_modes(hz, 10) == format_modes(hz, 0));
}

TEST_CASE("a parsed beam deck builds the aluminium cantilever of examples/beam_damper.toml") {
  const Deck deck = parse_deck(R"(
[structure]
kind = "beam"
length = 0.5
elements = 16
young = 7.0e10
density = 2700.0
section = { shape = "rectangle", width = 0.03, height = 0.005 }
supports = { start = "clamped", end = "free" }
damping_ratio = 0.01
[[damper]]
container = { shape = "box", size = [0.02, 0.02, 0.02] }
particles = { count = 10, diameter = 0.004, density = 7800.0 }
attach = { x = 0.4 }
[contact]
young = 2.0e11
[excitation]
kind = "free_decay"
initial_displacement = 0.001
duration = 0.1
)",
                               "inline.toml");
  const LinearStructure s = build_structure(deck);
  const double exact =
      kCantileverLambda[0] * kCantileverLambda[0] / (2 * kPi * 0.5 * 0.5) *
      std::sqrt(7.0e10 * (0.03 * 0.005 * 0.005 * 0.005 / 12) / (2700.0 * 0.03 * 0.005));
  CHECK(relative_error(natural_frequencies(s)[0], exact) > 0);
  CHECK(relative_error(natural_frequencies(s)[0], exact) < 1.5 * kEightElementError[0] / 16);
  CHECK(s.attachments.at(0).node == 13);  // 0.4 m / 31.25 mm = 12.8
}

}  // namespace
}  // namespace pdsim
