// Time integrators for M q'' + C q' + K q = f with f held constant over each step, in first
// order form y = [q; v], y' = A y + B f, A = [[0, I], [-M^-1 K, -M^-1 C]], B = [0; M^-1].
#include <cvode/cvode.h>
#include <nvector/nvector_serial.h>
#include <sundials/sundials_context.h>
#include <sundials/sundials_version.h>
#include <sunlinsol/sunlinsol_dense.h>
#include <sunmatrix/sunmatrix_dense.h>

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <stdexcept>
#include <string>
#include <type_traits>
#include <unsupported/Eigen/MatrixFunctions>

#include "structure/structure.hpp"

namespace pdsim {
namespace {

using Eigen::MatrixXd;
using Eigen::VectorXd;

// What both integrators share: the state and the kick.
class LinearIntegrator : public StructureIntegrator {
 public:
  explicit LinearIntegrator(const LinearStructure& s) : n_(s.size()), mass_factor_(s.mass) {
    if (mass_factor_.info() != Eigen::Success) {
      throw SimulationError("structure mass matrix cannot be factorised");
    }
    q = VectorXd::Zero(n_);
    v = VectorXd::Zero(n_);
  }
  void kick(const VectorXd& impulse) override { v += mass_factor_.solve(impulse); }

 protected:
  Eigen::Index n_;
  Eigen::LDLT<MatrixXd> mass_factor_;
};

// y_{n+1} = E y_n + G f with E = e^{A h}, G = int_0^h e^{A s} ds B, both read off
// exp([[A, B], [0, 0]] h) (Van Loan 1978, IEEE Trans. Autom. Control 23(3):395-404). A beam's
// A is badly scaled (omega_max^2 next to 1, stiff modes with omega h >> 1) and scaling and
// squaring then loses the slow modes (1e-3 errors on a 20-element cantilever), so the
// exponential is taken in balanced modal coordinates z = [eta; S^-1 eta'], eta = Phi^T M q
// (mass-normalised modes Phi), S = diag(max(omega_i, 1/h)), where undamped A is skew:
// z' = [[0, S], [-Omega^2 S^-1, -S^-1 Phi^T C Phi S]] z + [0; I] S^-1 Phi^T f; y = diag(Phi,
// Phi S) z.
class ExactIntegrator final : public LinearIntegrator {
 public:
  ExactIntegrator(const LinearStructure& s, double h) : LinearIntegrator(s) {
    Eigen::GeneralizedSelfAdjointEigenSolver<MatrixXd> eigen(s.stiffness, s.mass);
    if (eigen.info() != Eigen::Success) {
      throw SimulationError("structure eigenproblem failed to converge");
    }
    modes_ = eigen.eigenvectors();
    omega_squared_ = eigen.eigenvalues().cwiseMax(0.0);
    modal_damping_ = modes_.transpose() * s.damping * modes_;
    to_modal_ = modes_.transpose() * s.mass;
    nominal_ = propagator(h);
    state_ = VectorXd::Zero(2 * n_);
    next_ = VectorXd::Zero(2 * n_);
  }

  void step(double h, const VectorXd& load) override {
    const Propagator& p = h == nominal_.h ? nominal_ : other(h);
    state_ << q, v;
    next_.noalias() = p.state_map * state_;
    next_.noalias() += p.load_map * load;
    q = next_.head(n_);
    v = next_.tail(n_);
  }

 private:
  struct Propagator {
    double h = 0;                  // s
    MatrixXd state_map, load_map;  // E (2n x 2n), G (2n x n)
  };

  Propagator propagator(double h) const {
    if (!(h > 0)) throw std::invalid_argument("structure step must be positive");
    const Eigen::Index n = n_;
    const VectorXd scale = omega_squared_.cwiseSqrt().cwiseMax(1.0 / h);  // S, rad/s
    const VectorXd inverse_scale = scale.cwiseInverse();
    MatrixXd augmented = MatrixXd::Zero(3 * n, 3 * n);
    augmented.block(0, n, n, n) = (h * scale).asDiagonal();
    augmented.block(n, 0, n, n) = (-h * omega_squared_.cwiseProduct(inverse_scale)).asDiagonal();
    augmented.block(n, n, n, n) =
        -h * inverse_scale.asDiagonal() * modal_damping_ * scale.asDiagonal();
    augmented.block(n, 2 * n, n, n) = h * MatrixXd::Identity(n, n);
    const MatrixXd exponential = augmented.exp();

    MatrixXd to_physical = MatrixXd::Zero(2 * n, 2 * n), from_physical = to_physical;
    to_physical.topLeftCorner(n, n) = modes_;
    to_physical.bottomRightCorner(n, n) = modes_ * scale.asDiagonal();
    from_physical.topLeftCorner(n, n) = to_modal_;
    from_physical.bottomRightCorner(n, n) = inverse_scale.asDiagonal() * to_modal_;
    return {h, to_physical * exponential.topLeftCorner(2 * n, 2 * n) * from_physical,
            to_physical * exponential.topRightCorner(2 * n, n) * inverse_scale.asDiagonal() *
                modes_.transpose()};
  }

  const Propagator& other(double h) {
    if (h != other_.h) other_ = propagator(h);
    return other_;
  }

  MatrixXd modes_;          // Phi, mass-normalised
  VectorXd omega_squared_;  // (rad/s)^2
  MatrixXd modal_damping_;  // Phi^T C Phi
  MatrixXd to_modal_;       // Phi^T M = Phi^-1
  Propagator nominal_, other_;
  VectorXd state_, next_;
};

void check_flag(int flag, const char* function) {
  if (flag < 0) {
    throw SimulationError(std::string("CVODE: ") + function + " failed with flag " +
                          std::to_string(flag));
  }
}

template <typename T>
T check_created(T object, const char* function) {
  if (object == nullptr) throw SimulationError(std::string("CVODE: ") + function + " failed");
  return object;
}

struct ContextFree {
  void operator()(SUNContext c) const { SUNContext_Free(&c); }
};
struct VectorFree {
  void operator()(N_Vector x) const { N_VDestroy(x); }
};
struct MatrixFree {
  void operator()(SUNMatrix m) const { SUNMatDestroy(m); }
};
struct SolverFree {
  void operator()(SUNLinearSolver s) const { SUNLinSolFree(s); }
};
struct CvodeFree {
  void operator()(void* memory) const { CVodeFree(&memory); }
};

// CVODE (BDF, Newton with a dense direct solver and the exact Jacobian A), restarted at every
// step because the load jumps between coupling steps. Each step integrates t in [0, h]: the
// system is autonomous over a step, and a local clock keeps t + h free of rounding.
class CvodeIntegrator final : public LinearIntegrator {
 public:
  explicit CvodeIntegrator(const LinearStructure& s)
      : LinearIntegrator(s),
        system_(MatrixXd::Zero(2 * n_, 2 * n_)),
        load_rate_(VectorXd::Zero(2 * n_)) {
    system_.topRightCorner(n_, n_).setIdentity();
    system_.bottomLeftCorner(n_, n_) = -mass_factor_.solve(s.stiffness);
    system_.bottomRightCorner(n_, n_) = -mass_factor_.solve(s.damping);
    const auto size = static_cast<sunindextype>(2 * n_);
    SUNContext ctx = nullptr;
#if SUNDIALS_VERSION_MAJOR >= 7
    check_flag(SUNContext_Create(SUN_COMM_NULL, &ctx), "SUNContext_Create");
#else
    check_flag(SUNContext_Create(nullptr, &ctx), "SUNContext_Create");
#endif
    context_.reset(ctx);
    state_.reset(check_created(N_VNew_Serial(size, ctx), "N_VNew_Serial"));
    absolute_tolerance_.reset(check_created(N_VNew_Serial(size, ctx), "N_VNew_Serial"));
    jacobian_.reset(check_created(SUNDenseMatrix(size, size, ctx), "SUNDenseMatrix"));
    solver_.reset(
        check_created(SUNLinSol_Dense(state_.get(), jacobian_.get(), ctx), "SUNLinSol_Dense"));
    memory_.reset(check_created(CVodeCreate(CV_BDF, ctx), "CVodeCreate"));
    N_VConst(0.0, state_.get());
    N_VConst(1.0, absolute_tolerance_.get());
    check_flag(CVodeInit(memory_.get(), &CvodeIntegrator::rhs, 0.0, state_.get()), "CVodeInit");
    check_flag(CVodeSetUserData(memory_.get(), this), "CVodeSetUserData");
    check_flag(CVodeSetLinearSolver(memory_.get(), solver_.get(), jacobian_.get()),
               "CVodeSetLinearSolver");
    check_flag(CVodeSetJacFn(memory_.get(), &CvodeIntegrator::jacobian), "CVodeSetJacFn");
    check_flag(CVodeSetMaxNumSteps(memory_.get(), 100000), "CVodeSetMaxNumSteps");
    reference_rate_ = lowest_positive_frequency(s);
  }

  void step(double h, const VectorXd& load) override {
    if (!(h > 0)) throw std::invalid_argument("structure step must be positive");
    load_rate_.tail(n_) = mass_factor_.solve(load);
    const double q_max = q.lpNorm<Eigen::Infinity>(), v_max = v.lpNorm<Eigen::Infinity>();
    const double accel_max = load_rate_.lpNorm<Eigen::Infinity>();
    if (q_max == 0 && v_max == 0 && accel_max == 0) return;  // stays exactly at rest

    // Displacement scale from the state and the static response to the load, so that atol is
    // rtol relative to the motion even at a zero crossing or when starting from rest.
    const double w = reference_rate_;
    const double displacement_scale = std::max({q_max, v_max / w, accel_max / (w * w)});
    Eigen::Map<VectorXd> y(N_VGetArrayPointer(state_.get()), 2 * n_);
    Eigen::Map<VectorXd> atol(N_VGetArrayPointer(absolute_tolerance_.get()), 2 * n_);
    y << q, v;
    atol.head(n_).setConstant(kRelativeTolerance * displacement_scale);
    atol.tail(n_).setConstant(kRelativeTolerance * displacement_scale * w);

    void* cvode = memory_.get();
    check_flag(CVodeReInit(cvode, 0.0, state_.get()), "CVodeReInit");
    check_flag(CVodeSVtolerances(cvode, kRelativeTolerance, absolute_tolerance_.get()),
               "CVodeSVtolerances");
    check_flag(CVodeSetStopTime(cvode, h), "CVodeSetStopTime");
    sunrealtype reached = 0;
    check_flag(CVode(cvode, h, state_.get(), &reached, CV_NORMAL), "CVode");
    q = y.head(n_);
    v = y.tail(n_);
  }

 private:
  static constexpr double kRelativeTolerance = 1e-10;

  // rad/s; the inverse step for a structure without stiffness.
  static double lowest_positive_frequency(const LinearStructure& s) {
    Eigen::GeneralizedSelfAdjointEigenSolver<MatrixXd> eigen(s.stiffness, s.mass,
                                                             Eigen::EigenvaluesOnly);
    const double largest = eigen.eigenvalues().maxCoeff();
    for (const double omega2 : eigen.eigenvalues()) {
      if (omega2 > 1e-12 * largest) return std::sqrt(omega2);
    }
    return 1.0;
  }

  static int rhs(sunrealtype, N_Vector y, N_Vector ydot, void* user) {
    const auto* self = static_cast<const CvodeIntegrator*>(user);
    const Eigen::Index size = 2 * self->n_;
    Eigen::Map<VectorXd>(N_VGetArrayPointer(ydot), size).noalias() =
        self->system_ * Eigen::Map<const VectorXd>(N_VGetArrayPointer(y), size) + self->load_rate_;
    return 0;
  }

  static int jacobian(sunrealtype, N_Vector, N_Vector, SUNMatrix jac, void* user, N_Vector,
                      N_Vector, N_Vector) {
    const auto* self = static_cast<const CvodeIntegrator*>(user);
    const Eigen::Index size = 2 * self->n_;
    // SUNDIALS dense matrices are column-major and contiguous, like Eigen's default.
    Eigen::Map<MatrixXd>(SUNDenseMatrix_Data(jac), size, size) = self->system_;
    return 0;
  }

  MatrixXd system_;            // A
  VectorXd load_rate_;         // B f
  double reference_rate_ = 1;  // rad/s, relates velocity and displacement tolerances
  // Declaration order is release order reversed: the context outlives everything made in it.
  std::unique_ptr<std::remove_pointer_t<SUNContext>, ContextFree> context_;
  std::unique_ptr<std::remove_pointer_t<N_Vector>, VectorFree> state_, absolute_tolerance_;
  std::unique_ptr<std::remove_pointer_t<SUNMatrix>, MatrixFree> jacobian_;
  std::unique_ptr<std::remove_pointer_t<SUNLinearSolver>, SolverFree> solver_;
  std::unique_ptr<void, CvodeFree> memory_;
};

}  // namespace

std::unique_ptr<StructureIntegrator> make_integrator(const LinearStructure& s, IntegratorKind kind,
                                                     double h) {
  switch (kind) {
    case IntegratorKind::exact:
      return std::make_unique<ExactIntegrator>(s, h);
    case IntegratorKind::cvode:
      return std::make_unique<CvodeIntegrator>(s);
  }
  throw std::invalid_argument("unknown integrator kind");
}

}  // namespace pdsim
