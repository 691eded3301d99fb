// Structural models: the SDOF oscillator and the FEM beam (element matrices, assembly, supports,
// damping, modal reduction), their natural frequencies and the `pdsim modes` listing.
#include "structure/structure.hpp"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <cstdio>

namespace pdsim {
namespace {

using Eigen::MatrixXd;
using Eigen::VectorXd;

constexpr double kRectangleShearFactor = 5.0 / 6.0;

struct ElementMatrices {
  Eigen::Matrix4d stiffness, mass;
};

// Beam element of length le (m), DOFs (w1, theta1, w2, theta2). Timoshenko: the
// interdependent-interpolation element with shear parameter phi = 12 EI / (kappa G A le^2),
// translational and rotary consistent mass (Friedman & Kosmatka 1993, Comput. Struct.
// 47(3):473-481). phi = 0 without rotary inertia is the Euler-Bernoulli Hermite
// cubic element with consistent mass.
ElementMatrices beam_element(const BeamSpec& beam, double le) {
  const double bending_stiffness = beam.young * beam.inertia;  // EI, N m^2
  double phi = 0;
  if (beam.timoshenko) {
    const double shear_modulus = beam.young / (2 * (1 + beam.poisson));
    // The deck parser resolves the factor from the section shape; 0 means it did not.
    const double kappa = beam.shear_factor > 0 ? beam.shear_factor : kRectangleShearFactor;
    phi = 12 * bending_stiffness / (kappa * shear_modulus * beam.area * le * le);
  }
  const double l = le, l2 = le * le, p2 = phi * phi, shear_scale = (1 + phi) * (1 + phi);
  ElementMatrices e;
  e.stiffness << 12, 6 * l, -12, 6 * l,               //
      6 * l, (4 + phi) * l2, -6 * l, (2 - phi) * l2,  //
      -12, -6 * l, 12, -6 * l,                        //
      6 * l, (2 - phi) * l2, -6 * l, (4 + phi) * l2;
  e.stiffness *= bending_stiffness / ((1 + phi) * l2 * l);

  const double a = 70 * p2 + 147 * phi + 78, b = (35 * p2 + 77 * phi + 44) * l / 4,
               c = 35 * p2 + 63 * phi + 27, d = (35 * p2 + 63 * phi + 26) * l / 4,
               g = (7 * p2 + 14 * phi + 8) * l2 / 4, h = (7 * p2 + 14 * phi + 6) * l2 / 4;
  e.mass << a, b, c, -d,  //
      b, g, d, -h,        //
      c, d, a, -b,        //
      -d, -h, -b, g;
  e.mass *= beam.density * beam.area * l / (210 * shear_scale);
  if (beam.timoshenko) {
    const double s = (3 - 15 * phi) * l, r = (4 + 5 * phi + 10 * p2) * l2,
                 t = (-1 - 5 * phi + 5 * p2) * l2;
    Eigen::Matrix4d rotary;
    rotary << 36, s, -36, s,  //
        s, r, -s, t,          //
        -36, -s, 36, -s,      //
        s, t, -s, r;
    e.mass += rotary * (beam.density * beam.inertia / (30 * shear_scale * l));
  }
  return e;
}

MatrixXd symmetric_part(const MatrixXd& a) {
  return 0.5 * (a + a.transpose());
}

LinearStructure build_sdof(const StructureSpec& spec, std::size_t dampers_count) {
  LinearStructure s;
  s.mass = MatrixXd::Constant(1, 1, spec.mass);
  s.damping = MatrixXd::Constant(1, 1, spec.damping);
  s.stiffness = MatrixXd::Constant(1, 1, spec.stiffness);
  s.base_influence = VectorXd::Ones(1);
  s.base_mass = spec.mass;
  s.force_shape = VectorXd::Ones(1);
  const auto dampers = static_cast<Eigen::Index>(dampers_count);
  s.attachments.assign(dampers_count, Attachment{0, -1, 0.0, 0});
  s.attachment_translation = MatrixXd::Ones(dampers, 1);
  s.attachment_rotation = MatrixXd::Zero(dampers, 1);
  s.response = Eigen::RowVectorXd::Ones(1);
  s.response_dof = 0;
  return s;
}

// Node a damper is bolted to: attach.node, or attach.x snapped to the nearest node.
int attachment_node(const BeamSpec& beam, const Mount& mount, std::size_t damper,
                    double element_length, const Locate& where) {
  const std::string key = "damper[" + std::to_string(damper) + "].attach";
  if (mount.x) {
    const double x = *mount.x;
    if (!(x >= 0 && x <= beam.length)) {
      throw InputError(where(key), key,
                       "x = " + std::to_string(x) + " m is outside the beam [0, " +
                           std::to_string(beam.length) + "] m");
    }
    return static_cast<int>(std::lround(x / element_length));
  }
  if (mount.node < 0 || mount.node > beam.elements) {
    throw InputError(where(key), key,
                     "expected { node = 0.." + std::to_string(beam.elements) +
                         " } or { x = <m> } for a damper on a beam");
  }
  return mount.node;
}

LinearStructure build_beam(const StructureSpec& spec, const std::vector<Mount>& mounts,
                           const Locate& where) {
  const BeamSpec& beam = spec.beam;
  if (beam.elements < 1 || !(beam.length > 0)) {
    throw InputError(where("structure"), "structure", "a beam needs length > 0 and elements >= 1");
  }
  const int nodes = beam.elements + 1;
  const double le = beam.length / beam.elements;

  // Physical DOF 2 k is w of node k, 2 k + 1 its rotation; constrained DOFs are dropped.
  std::vector<bool> constrained(static_cast<std::size_t>(2 * nodes), false);
  auto constrain = [&](Support support, int node) {
    if (support == Support::free) return;
    constrained[static_cast<std::size_t>(2 * node)] = true;
    if (support == Support::clamped) constrained[static_cast<std::size_t>(2 * node + 1)] = true;
  };
  constrain(beam.start, 0);
  constrain(beam.end, nodes - 1);
  std::vector<int> free_dofs, free_index(constrained.size(), -1);
  for (std::size_t i = 0; i < constrained.size(); ++i) {
    if (constrained[i]) continue;
    free_index[i] = static_cast<int>(free_dofs.size());
    free_dofs.push_back(static_cast<int>(i));
  }
  const auto n = static_cast<Eigen::Index>(free_dofs.size());

  MatrixXd mass_full = MatrixXd::Zero(2 * nodes, 2 * nodes);
  MatrixXd stiffness_full = MatrixXd::Zero(2 * nodes, 2 * nodes);
  const ElementMatrices element = beam_element(beam, le);  // uniform beam: one element
  for (int k = 0; k < beam.elements; ++k) {
    mass_full.block<4, 4>(2 * k, 2 * k) += element.mass;
    stiffness_full.block<4, 4>(2 * k, 2 * k) += element.stiffness;
  }

  LinearStructure s;
  s.mass = mass_full(free_dofs, free_dofs);
  s.stiffness = stiffness_full(free_dofs, free_dofs);
  // Supports moving rigidly by y load the free DOFs with -(M_ff r_f + M_fc r_c) y'' (Chopra,
  // Dynamics of Structures, multiple-support excitation): with consistent mass the supports'
  // coupling M_fc counts, so r = M_ff^-1 (M_ff r_f + M_fc r_c).
  VectorXd rigid_translation = VectorXd::Zero(2 * nodes);
  for (int k = 0; k < nodes; ++k) rigid_translation(2 * k) = 1;
  const VectorXd support_inertia = mass_full(free_dofs, Eigen::all) * rigid_translation;
  s.base_influence = s.mass.ldlt().solve(support_inertia);
  s.base_mass = rigid_translation.dot(mass_full * rigid_translation);

  const auto dampers = static_cast<Eigen::Index>(mounts.size());
  s.attachment_translation = MatrixXd::Zero(dampers, n);
  s.attachment_rotation = MatrixXd::Zero(dampers, n);
  for (std::size_t i = 0; i < mounts.size(); ++i) {
    const int node = attachment_node(beam, mounts[i], i, le, where);
    Attachment a;
    a.node = node;
    a.x = node * le;
    a.translation_dof = free_index[static_cast<std::size_t>(2 * node)];
    a.rotation_dof = free_index[static_cast<std::size_t>(2 * node + 1)];
    const auto row = static_cast<Eigen::Index>(i);
    if (a.translation_dof >= 0) s.attachment_translation(row, a.translation_dof) = 1;
    if (a.rotation_dof >= 0) s.attachment_rotation(row, a.rotation_dof) = 1;
    s.attachments.push_back(a);
  }
  const int loaded_node = s.attachments.empty() ? nodes - 1 : s.attachments.front().node;
  s.response_dof = free_index[static_cast<std::size_t>(2 * loaded_node)];
  s.response = Eigen::RowVectorXd::Zero(n);
  s.force_shape = VectorXd::Zero(n);
  if (s.response_dof >= 0) {
    s.response(s.response_dof) = 1;
    s.force_shape(s.response_dof) = 1;
  }

  // Modes are needed for modal damping and for reduction; eigenvectors come mass-normalised.
  const bool reduce = spec.modes > 0;
  const bool modal_damping = !spec.rayleigh && spec.damping_ratio > 0;
  MatrixXd modes;
  VectorXd omega;  // rad/s
  if (reduce || modal_damping) {
    Eigen::GeneralizedSelfAdjointEigenSolver<MatrixXd> eigen(s.stiffness, s.mass);
    if (eigen.info() != Eigen::Success) throw_no_modes(where);
    modes = eigen.eigenvectors();
    omega = eigen.eigenvalues().cwiseMax(0.0).cwiseSqrt();
  }
  if (spec.rayleigh) {
    s.damping = (*spec.rayleigh)[0] * s.mass + (*spec.rayleigh)[1] * s.stiffness;
  } else if (modal_damping) {
    // C = M Phi diag(2 zeta omega_i) Phi^T M (Chopra, Dynamics of Structures, classical damping).
    const MatrixXd mass_modes = s.mass * modes;
    s.damping = symmetric_part(mass_modes * (2 * spec.damping_ratio * omega).asDiagonal() *
                               mass_modes.transpose());
  } else {
    s.damping = MatrixXd::Zero(n, n);
  }

  if (reduce) {
    if (spec.modes > n) {
      throw InputError(
          where("structure.modes"), "structure.modes",
          "expected at most " + std::to_string(n) + " (the number of free DOFs of the beam)");
    }
    const MatrixXd kept = modes.leftCols(spec.modes);
    s.base_influence = kept.transpose() * support_inertia;
    s.mass = symmetric_part(kept.transpose() * s.mass * kept);
    s.stiffness = symmetric_part(kept.transpose() * s.stiffness * kept);
    s.damping = symmetric_part(kept.transpose() * s.damping * kept);
    s.force_shape = kept.transpose() * s.force_shape;
    s.attachment_translation = s.attachment_translation * kept;
    s.attachment_rotation = s.attachment_rotation * kept;
    s.response = s.response * kept;
  }
  return s;
}

}  // namespace

[[noreturn]] void throw_no_modes(const Locate& where) {
  throw InputError(where("structure"), "structure",
                   "expected a structure whose mass and stiffness matrices have modes (their "
                   "eigenproblem failed): look for an absurd density, young, section or mass");
}

LinearStructure build_structure(const StructureSpec& spec, const std::vector<Mount>& mounts,
                                const Locate& where) {
  switch (spec.kind) {
    case StructureKind::sdof:
      return build_sdof(spec, mounts.size());
    case StructureKind::beam:
      return build_beam(spec, mounts, where);
    case StructureKind::none:
      break;
  }
  throw InputError(where("structure"), "structure.kind",
                   "no structure to build (expected \"sdof\" or \"beam\")");
}

Eigen::VectorXcd harmonic_response(const LinearStructure& s, double omega,
                                   const Eigen::VectorXcd& load,
                                   const std::vector<std::complex<double>>& impedance,
                                   std::complex<double> base) {
  const std::complex<double> i(0, 1);
  Eigen::MatrixXcd dynamic = (s.stiffness - omega * omega * s.mass).cast<std::complex<double>>() +
                             i * omega * s.damping.cast<std::complex<double>>();
  Eigen::VectorXcd rhs = load;
  for (std::size_t k = 0; k < impedance.size(); ++k) {
    const Eigen::VectorXcd t =
        s.attachment_translation.row(static_cast<int>(k)).transpose().cast<std::complex<double>>();
    dynamic += impedance[k] * t * t.transpose();
    rhs -= impedance[k] * base * t;
  }
  return dynamic.partialPivLu().solve(rhs);
}

Eigen::VectorXd static_response(const LinearStructure& s, const Eigen::VectorXd& load) {
  const Eigen::LDLT<MatrixXd> ldlt(s.stiffness);
  if (ldlt.info() != Eigen::Success || !ldlt.isPositive() ||
      ldlt.vectorD().minCoeff() <= 1e-12 * ldlt.vectorD().maxCoeff())
    return VectorXd::Zero(s.size());
  return ldlt.solve(load);
}

std::vector<double> natural_frequencies(const LinearStructure& s) {
  Eigen::GeneralizedSelfAdjointEigenSolver<MatrixXd> eigen(s.stiffness, s.mass,
                                                           Eigen::EigenvaluesOnly);
  if (eigen.info() != Eigen::Success) throw SimulationError("eigenproblem failed to converge");
  std::vector<double> hz;
  for (const double omega2 : eigen.eigenvalues()) {
    hz.push_back(std::sqrt(std::max(omega2, 0.0)) / (2 * kPi));
  }
  return hz;
}

std::string format_modes(const std::vector<double>& hz, int count) {
  std::size_t shown = hz.size();
  if (count > 0) shown = std::min(shown, static_cast<std::size_t>(count));
  std::string out;
  char line[64];
  for (std::size_t k = 0; k < shown; ++k) {
    std::snprintf(line, sizeof line, "mode %zu %.6g Hz\n", k + 1, hz[k]);
    out += line;
  }
  return out;
}

}  // namespace pdsim
