// The non-smooth step on the CPU (what it solves: kernels/nonsmooth.hpp). A step lists the
// contacts within the envelope (pairs from the neighbour lists, walls from the container's
// shape, in particle and slot order), solves their impulses by APGD warm-started from the last
// step's, and integrates. Every sum over particles or contacts is taken in blocks fixed by the
// problem, never by the threads, so results do not depend on the thread count.
#include <omp.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <vector>

#include "kernels/cpu/engine_cpu.hpp"

namespace pdsim {
namespace cpu_engine {
namespace {

// What the solver's passes read of a contact.
struct Frame {
  Vec3 n, t1, t2;              // the frame, n from the partner to i
  double ri = 0, rj = 0;       // arms along n (rj = 0 for a wall)
  std::int32_t i = 0, j = -1;  // j < 0: a wall
};
// One contact of a step.
struct Contact : Frame {
  std::int32_t slot = 0;  // its impulse's history slot (walls: kWallSlots per particle)
  double wall_gap = 0;    // wall: the centre's distance (the reaction's lever)
  Vec3 w;                 // wall: its velocity at the contact point
  Vec3 u0;                // relative velocity at the step's start
  Vec3 warm;              // the last step's impulse (N s), zero for a new contact
  double b = 0;           // target normal speed (m/s)
};

// The process's solver totals (nonsmooth_totals()).
std::atomic<long long> total_steps{0}, total_iterations{0}, total_contacts{0}, total_capped{0};
std::atomic<int> total_most{0};
std::atomic<double> total_worst{0};

template <class T>
void raise_to(std::atomic<T>& a, T v) {
  T seen = a.load(std::memory_order_relaxed);
  while (seen < v && !a.compare_exchange_weak(seen, v, std::memory_order_relaxed)) {
  }
}

constexpr int kSumBlock = 256;  // contacts per partial sum (fixed: sums independent of threads)
// The first Lipschitz estimate, in largest diagonal entries of N: 1, 2 and 4 took 20.6, 18.9
// and 21.0 iterations a step on the shaken Saeki pile.
constexpr double kFirstLipschitz = 2.0;

template <class V>
class Solver final : public NonsmoothStep {
  static constexpr int R = V::Tangential::kRows;

 public:
  explicit Solver(const NonsmoothParams& p) : p_(p) {}

  void step(const ParticleStepArgs& a, int threads, StepTotals& totals) override {
    const int n = a.count;
    const int blocks = (n + kBlock - 1) / kBlock;
    parallel_ = threads > 1 && blocks > 1;
    threads_ = threads;
    block_contacts_.resize(static_cast<std::size_t>(blocks));
    block_totals_.assign(static_cast<std::size_t>(blocks), StepTotals{});
    each(blocks, 1, [&](int b) {
      detect(b * kBlock, std::min(n, (b + 1) * kBlock), a, block_contacts_[b], block_totals_[b]);
    });
    c_.clear();
    for (const auto& list : block_contacts_) c_.insert(c_.end(), list.begin(), list.end());
    const int m = static_cast<int>(c_.size());
    dv_.assign(6 * static_cast<std::size_t>(n), 0.0);
    int iterations = 0;
    double residual = 0;
    if (m > 0) {
      link(n);
      residual = solve(a, iterations);
      gather(best_.data(), a);
    }
    integrate(a, totals);
    finish(a, totals);
    for (const auto& t : block_totals_) totals.flags |= t.flags;
    total_steps.fetch_add(1, std::memory_order_relaxed);
    total_iterations.fetch_add(iterations, std::memory_order_relaxed);
    total_contacts.fetch_add(m, std::memory_order_relaxed);
    if (iterations >= p_.max_iterations && residual > p_.tolerance)
      total_capped.fetch_add(1, std::memory_order_relaxed);
    raise_to(total_most, iterations);
    raise_to(total_worst, residual);
  }

 private:
  double inv_mass(const ParticleStepArgs& a, int i) const {
    return V::kPolydisperse ? a.inv_mass[i] : a.mono.inv_mass;
  }
  double inv_inertia(const ParticleStepArgs& a, int i) const {
    return V::kPolydisperse ? a.inv_inertia[i] : a.mono.inv_inertia;
  }
  static Vec3 position(const ParticleArrays& s, int i) { return {s.x[i], s.y[i], s.z[i]}; }
  static Vec3 velocity(const ParticleArrays& s, int i) { return {s.vx[i], s.vy[i], s.vz[i]}; }
  static Vec3 spin(const ParticleArrays& s, int i) { return {s.wx[i], s.wy[i], s.wz[i]}; }

  // The relative velocity of contact c for the bodies' velocities and spins given.
  static Vec3 relative(const Contact& c, Vec3 vi, Vec3 wi, Vec3 vj, Vec3 wj) {
    return vi - c.ri * cross(wi, c.n) - vj - c.rj * cross(wj, c.n) - c.w;
  }
  Vec3 relative_now(const Contact& c, const ParticleArrays& s) const {
    const Vec3 vj = c.j >= 0 ? velocity(s, c.j) : Vec3{};
    const Vec3 wj = c.j >= 0 ? spin(s, c.j) : Vec3{};
    return relative(c, velocity(s, c.i), spin(s, c.i), vj, wj);
  }
  void frame(Contact& c, const ParticleStepArgs& a, double gap) const {
    tangent_frame(c.n, c.t1, c.t2);
    c.u0 = relative_now(c, a.in);
    c.b = target_speed(gap, dot(c.u0, c.n), a.dt, p_);
  }

  // The contacts of particles [begin, end): their partners within the envelope, then their
  // walls; marks them in the history's output masks.
  void detect(int begin, int end, const ParticleStepArgs& a, std::vector<Contact>& out,
              StepTotals& sum) const {
    out.clear();
    for (int i = begin; i < end; ++i) {
      const double ri = V::kPolydisperse ? a.radius[i] : a.mono_radius;
      const Vec3 xi = position(a.in, i);
      const int base = a.slot_start[i];
      const std::uint64_t had = a.history.neighbour_mask_in[i];
      std::uint64_t listed = 0;
      for (int k = 0; k < a.neighbour_count[i]; ++k) {
        const int j = a.neighbours[base + k];
        const double rj = V::kPolydisperse ? a.radius[j] : a.mono_radius;
        const Vec3 d = xi - position(a.in, j);
        const double dist = norm(d);
        const double gap = dist - ri - rj;
        if (gap >= p_.envelope) continue;
        listed |= std::uint64_t{1} << k;
        Contact c;
        c.i = i, c.j = j, c.slot = base + k;
        c.n = (1.0 / dist) * d;
        c.ri = ri, c.rj = rj;
        if (had >> k & 1u) c.warm = load3(a.history.neighbour_in, c.slot);
        frame(c, a, gap);
        out.push_back(c);
      }
      a.history.neighbour_mask_out[i] = listed;

      Vec3 offset, local;
      container_offset<V>(xi, a, offset, local);
      if (!ShapeOf<V::kShape>::near(local, ri + p_.envelope, a.geometry)) {
        a.history.wall_mask_out[i] = 0;
        continue;
      }
      walls_within<V>(i, ri + p_.envelope, a, sum, [&](int slot, bool held, double gap, Vec3 n) {
        Contact c;
        c.i = i, c.slot = i * kWallSlots + slot;
        c.n = n;
        c.ri = ri;
        c.wall_gap = gap;
        c.w = a.container.velocity;
        if constexpr (V::kRotating) c.w += cross(a.container.angular_velocity, offset - gap * n);
        if (held) c.warm = load3(a.history.wall_in, c.slot);
        frame(c, a, gap - ri);
        out.push_back(c);
      });
    }
  }

  // The body -> contact links: entries contact << 1 | 1 where the body is the contact's second.
  void link(int n) {
    start_.assign(static_cast<std::size_t>(n) + 1, 0);
    for (const Contact& c : c_) {
      ++start_[c.i + 1];
      if (c.j >= 0) ++start_[c.j + 1];
    }
    for (int b = 0; b < n; ++b) start_[b + 1] += start_[b];
    entry_.resize(static_cast<std::size_t>(start_[n]));
    fill_.assign(start_.begin(), start_.end() - 1);
    arm_.resize(entry_.size());
    for (int k = 0; k < static_cast<int>(c_.size()); ++k) {
      arm_[fill_[c_[k].i]] = c_[k].ri;
      entry_[fill_[c_[k].i]++] = k << 1;
      if (c_[k].j >= 0) arm_[fill_[c_[k].j]] = c_[k].rj, entry_[fill_[c_[k].j]++] = k << 1 | 1;
    }
    pq_.resize(6 * c_.size());
  }

  Vec3 impulse(const double* x, int k) const {
    const Frame& c = c_[k];
    const double* g = x + R * static_cast<std::ptrdiff_t>(k);
    if constexpr (R == 3) return g[0] * c.n + g[1] * c.t1 + g[2] * c.t2;
    return g[0] * c.n;
  }

  // dv_: each body's velocity and spin change under the contacts' impulses x. Each contact's
  // impulse P and n x P first (pq_), then each body sums its contacts' (its spin changes by
  // -r n x P / I as first or second body alike).
  void gather(const double* x, const ParticleStepArgs& a) {
    each(static_cast<int>(c_.size()), kSumBlock, [&](int k) {
      const Vec3 p = impulse(x, k), q = cross(c_[k].n, p);
      double* o = pq_.data() + 6 * static_cast<std::ptrdiff_t>(k);
      o[0] = p.x, o[1] = p.y, o[2] = p.z, o[3] = q.x, o[4] = q.y, o[5] = q.z;
    });
    each(a.count, kBlock, [&](int b) {
      Vec3 dv, dw;
      for (int e = start_[b]; e < start_[b + 1]; ++e) {
        const double* o = pq_.data() + 6 * static_cast<std::ptrdiff_t>(entry_[e] >> 1);
        const Vec3 p{o[0], o[1], o[2]}, q{o[3], o[4], o[5]};
        dv += (entry_[e] & 1) ? -1.0 * p : p;
        dw -= arm_[e] * q;
      }
      dv = inv_mass(a, b) * dv;
      dw = inv_inertia(a, b) * dw;
      double* d = dv_.data() + 6 * static_cast<std::ptrdiff_t>(b);
      d[0] = dv.x, d[1] = dv.y, d[2] = dv.z, d[3] = dw.x, d[4] = dw.y, d[5] = dw.z;
    });
  }

  // A pass over the contacts in blocks of kSumBlock, f(k, sums) adding contact k's terms to
  // its block's Sums; the blocks' sums are then combined in block order (Sums::add), so that
  // they do not depend on the threads.
  template <class Sums, class F>
  Sums blocked(F&& f) {
    const int m = static_cast<int>(c_.size());
    const int blocks = (m + kSumBlock - 1) / kSumBlock;
    auto block = [&](int b) {
      Sums sums;
      for (int k = b * kSumBlock; k < std::min(m, (b + 1) * kSumBlock); ++k) f(k, sums);
      return sums;
    };
    Sums total;
    if (!parallel_) {
      for (int b = 0; b < blocks; ++b) total.add(block(b));
      return total;
    }
    std::vector<Sums> parts(static_cast<std::size_t>(blocks));
#pragma omp parallel for num_threads(threads_) schedule(static)
    for (int b = 0; b < blocks; ++b) parts[b] = block(b);
    for (const Sums& part : parts) total.add(part);
    return total;
  }
  struct Sum {
    double value = 0;
    void add(const Sum& o) { value += o.value; }
  };

  // out = N x, the contacts' relative velocity changes under the impulses x; returns the
  // objective 1/2 x.Nx + r.x.
  double product(const double* x, double* out, const ParticleStepArgs& a) {
    gather(x, a);
    return blocked<Sum>([&](int k, Sum& f) {
             const Frame& c = c_[k];
             const double* di = dv_.data() + 6 * static_cast<std::ptrdiff_t>(c.i);
             Vec3 u = Vec3{di[0], di[1], di[2]} - c.ri * cross(Vec3{di[3], di[4], di[5]}, c.n);
             if (c.j >= 0) {
               const double* dj = dv_.data() + 6 * static_cast<std::ptrdiff_t>(c.j);
               u -= Vec3{dj[0], dj[1], dj[2]} + c.rj * cross(Vec3{dj[3], dj[4], dj[5]}, c.n);
             }
             double* o = out + R * static_cast<std::ptrdiff_t>(k);
             const double* g = x + R * static_cast<std::ptrdiff_t>(k);
             const double* r = r_.data() + R * static_cast<std::ptrdiff_t>(k);
             o[0] = dot(u, c.n);
             if constexpr (R == 3) o[1] = dot(u, c.t1), o[2] = dot(u, c.t2);
             for (int q = 0; q < R; ++q) f.value += g[q] * (0.5 * o[q] + r[q]);
           })
        .value;
  }

  // f(k) for k < n: over the threads in chunks of `chunk` in a large scene, else in this one
  // (an OpenMP region, even of one thread, keeps the loop from being inlined).
  template <class F>
  void each(int n, int chunk, F&& f) {
    if (!parallel_) {
      for (int k = 0; k < n; ++k) f(k);
      return;
    }
#pragma omp parallel for num_threads(threads_) schedule(static, chunk)
    for (int k = 0; k < n; ++k) f(k);
  }

  void project(double* g, double mu) const {
    if constexpr (R == 3)
      project_cone(g[0], g[1], g[2], mu);
    else
      g[0] = max_of(g[0], 0.0);
  }

  // What the projected step z = P(y - t g) from y (g = N y + r, its gradient) gives: the
  // largest |z - y|^2 of a contact (|z - y| / t is the gradient projected on the cones: the
  // residual, m/s), g.(z - x) (the restart test) and g.(z - y) + L/2 |z - y|^2 (the line
  // search's bound).
  struct Step {
    double largest = 0, uphill = 0, bound = 0;
    void add(const Step& o) {
      largest = max_of(largest, o.largest), uphill += o.uphill, bound += o.bound;
    }
  };

  // APGD (Mazhar et al. 2015, algorithm 2): Nesterov's momentum, the step from a backtracking
  // Lipschitz estimate, restarted where the momentum points uphill. The residual is the
  // projected gradient at the extrapolated point y, the step from it kept in best_ where it is
  // the lowest so far; returns that residual, `iterations` the products N z taken.
  double solve(const ParticleStepArgs& a, int& iterations) {
    const int m = static_cast<int>(c_.size());
    const std::size_t size = static_cast<std::size_t>(R) * m;
    for (auto* v : {&r_, &x_, &nx_, &y_, &ny_, &z_, &nz_, &best_}) v->assign(size, 0.0);
    // r = J v* - w - b e_n: gravity changes a wall contact's relative velocity, not a pair's.
    const Vec3 free_fall = V::kGravity ? a.dt * a.gravity : Vec3{};
    for (int k = 0; k < m; ++k) {
      const Contact& c = c_[k];
      const Vec3 u = c.j >= 0 ? c.u0 : c.u0 + free_fall;
      double* r = r_.data() + R * k;
      double* x = x_.data() + R * k;
      r[0] = dot(u, c.n) - c.b;
      x[0] = dot(c.warm, c.n);
      if constexpr (R == 3) {
        r[1] = dot(u, c.t1), r[2] = dot(u, c.t2);
        x[1] = dot(c.warm, c.t1), x[2] = dot(c.warm, c.t2);
      }
      project(x, p_.friction);
    }
    // The Lipschitz constant's first estimate: a multiple of the largest diagonal entry of N
    // (what one contact alone asks); backtracking doubles it where too low. From the step's own
    // contacts, so that a restored checkpoint goes on as the run did.
    double lipschitz = 0;
    for (const Frame& f : c_) {
      const double mi = inv_mass(a, f.i), mj = f.j >= 0 ? inv_mass(a, f.j) : 0.0;
      double diag = mi + mj;
      if constexpr (R == 3)
        diag += f.ri * f.ri * inv_inertia(a, f.i) +
                (f.j >= 0 ? f.rj * f.rj * inv_inertia(a, f.j) : 0.0);
      lipschitz = max_of(lipschitz, diag);
    }
    lipschitz *= kFirstLipschitz;
    double fy = product(x_.data(), nx_.data(), a);  // from the warm start
    y_ = x_, ny_ = nx_;
    double theta = 1, best = 1e300;
    iterations = 0;
    for (;;) {
      double fz = 0;
      Step step;
      for (int doubled = 0;; ++doubled) {
        const double t = 1 / lipschitz;
        step = blocked<Step>([&](int k, Step& sums) {
          double d = 0;
          for (int q = 0; q < R; ++q) {
            const int i = R * k + q;
            z_[i] = y_[i] - t * (ny_[i] + r_[i]);
          }
          project(z_.data() + R * k, p_.friction);
          for (int q = 0; q < R; ++q) {
            const int i = R * k + q;
            const double g = ny_[i] + r_[i], dz = z_[i] - y_[i];
            d += dz * dz;
            sums.uphill += g * (z_[i] - x_[i]);
            sums.bound += g * dz;
          }
          sums.largest = max_of(sums.largest, d);
          sums.bound += 0.5 * lipschitz * d;
        });
        const double res = std::sqrt(step.largest) * lipschitz;
        if (res < best) best = res, best_ = z_;
        if (res <= p_.tolerance || iterations >= p_.max_iterations) {
          return best;
        }
        fz = product(z_.data(), nz_.data(), a);
        ++iterations;
        if (fz <= fy + step.bound + 1e-14 * std::fabs(fy) || doubled == 60) break;
        lipschitz *= 2;
      }
      if (step.uphill > 0) {  // restart: the momentum has carried the iterate uphill
        y_ = z_, ny_ = nz_;
        fy = fz;
        theta = 1;
      } else {
        const double theta_next = 0.5 * (-theta * theta + theta * std::sqrt(theta * theta + 4));
        const double beta = theta * (1 - theta) / (theta * theta + theta_next);
        fy = blocked<Sum>([&](int k, Sum& f) {
               for (int q = 0; q < R; ++q) {
                 const int i = R * k + q;
                 y_[i] = z_[i] + beta * (z_[i] - x_[i]);
                 ny_[i] = nz_[i] + beta * (nz_[i] - nx_[i]);
                 f.value += y_[i] * (0.5 * ny_[i] + r_[i]);
               }
             }).value;
        theta = theta_next;
      }
      x_.swap(z_), nx_.swap(nz_);
      lipschitz *= 0.9;
    }
  }

  // v+ = v + dt g + dv, x+ = x + dt v+ (dv_ holds the impulses' changes, or zeros).
  void integrate(const ParticleStepArgs& a, StepTotals& totals) {
    const int n = a.count;
    const int blocks = (n + kBlock - 1) / kBlock;
    each(blocks, 1, [&](int b) {
      StepTotals& sum = block_totals_[b];
      for (int i = b * kBlock; i < std::min(n, (b + 1) * kBlock); ++i) {
        const double* d = dv_.data() + 6 * static_cast<std::ptrdiff_t>(i);
        Vec3 v = velocity(a.in, i) + Vec3{d[0], d[1], d[2]};
        if constexpr (V::kGravity) v += a.dt * a.gravity;
        const Vec3 w = spin(a.in, i) + Vec3{d[3], d[4], d[5]};
        const Vec3 x = position(a.in, i) + a.dt * v;
        a.out.x[i] = x.x, a.out.y[i] = x.y, a.out.z[i] = x.z;
        a.out.vx[i] = v.x, a.out.vy[i] = v.y, a.out.vz[i] = v.z;
        a.out.wx[i] = w.x, a.out.wy[i] = w.y, a.out.wz[i] = w.z;
        const double mass = 1 / inv_mass(a, i), inertia = 1 / inv_inertia(a, i);
        sum.kinetic += 0.5 * (mass * dot(v, v) + inertia * dot(w, w));
        sum.speed_sq = max_of(sum.speed_sq, dot(v, v));
      }
    });
    for (const auto& t : block_totals_) {
      totals.kinetic += t.kinetic;
      totals.speed_sq = max_of(totals.speed_sq, t.speed_sq);
    }
  }

  // Each contact's impulse into its history, its work into the tallies (minus the impulse
  // times the mean of its relative velocities before and after: what the bodies' kinetic
  // energy loses to it, the container's work aside), a wall's reaction onto the container.
  void finish(const ParticleStepArgs& a, StepTotals& totals) {
    for (std::size_t k = 0; k < c_.size(); ++k) {
      const Contact& c = c_[k];
      const Vec3 p = impulse(best_.data(), static_cast<int>(k));
      store3(c.j >= 0 ? a.history.neighbour_out : a.history.wall_out, c.slot, p);
      // The positions moved; the frame and arms are the step's, as in the solve.
      Vec3 vj, wj;
      if (c.j >= 0) vj = velocity(a.out, c.j), wj = spin(a.out, c.j);
      const Vec3 mean = 0.5 * (c.u0 + relative(c, velocity(a.out, c.i), spin(a.out, c.i), vj, wj));
      const double normal = dot(p, c.n) * dot(mean, c.n);
      totals.tally.normal -= normal;
      totals.tally.tangential -= dot(p, mean) - normal;
      if (c.j < 0) add_wall_reaction<V>(c.i, c.wall_gap, c.n, (1 / a.dt) * p, a, totals);
    }
  }

  NonsmoothParams p_;
  bool parallel_ = false;
  int threads_ = 1;
  std::vector<std::vector<Contact>> block_contacts_;
  std::vector<StepTotals> block_totals_;
  std::vector<Contact> c_;
  std::vector<std::int32_t> start_, entry_, fill_;
  std::vector<double> arm_;  // per entry: the body's arm (its radius)
  std::vector<double> pq_;   // per contact: P and n x P (gather())
  std::vector<double> dv_;   // 6 per body
  // R per contact: r, the iterates x (and N x), y (and N y), the trial z (and N z), the best
  // step.
  std::vector<double> r_, x_, nx_, y_, ny_, z_, nz_, best_;
};

struct MakeSolver {
  const NonsmoothParams& p;
  template <class V>
  NonsmoothVariant operator()() const {
    VariantInfo info = variant_info<V>();
    info.pair_doubles = 0;  // no pair loads: the impulses are solved together
    return {std::make_unique<Solver<V>>(p), std::move(info)};
  }
};

}  // namespace

NonsmoothVariant make_nonsmooth_step(const EngineConfig& config) {
  const NonsmoothParams& p = *config.nonsmooth;
  if (p.friction > 0)
    return dispatch_detail::by_gravity<NonsmoothNormal, ConeFriction, false>(config, MakeSolver{p});
  return dispatch_detail::by_gravity<NonsmoothNormal, NoFriction, false>(config, MakeSolver{p});
}

}  // namespace cpu_engine

SolverTotals nonsmooth_totals() {
  using namespace cpu_engine;
  return {total_steps.load(),  total_iterations.load(), total_contacts.load(),
          total_capped.load(), total_most.load(),       total_worst.load()};
}

}  // namespace pdsim
