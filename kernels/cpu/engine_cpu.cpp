// The CPU engine: particles, neighbour lists, rebuilds and checkpoints, compiled once. Per kernel
// variant only its two passes (CpuStep, engine_cpu.hpp) differ; they are compiled in translation
// units that CMake generates from engine_cpu_variants.cpp.in, one per normal law, tangential law
// and rolling choice, so that the build compiles them in parallel.
#include <omp.h>

#include <algorithm>
#include <atomic>
#include <numeric>

#include "kernels/cpu/engine_cpu.hpp"
#include "kernels/engine_core.hpp"

namespace pdsim {
namespace cpu_engine {
namespace {

template <class T>
using CpuArray = std::vector<T>;

// a[i] = a[order[i]] (stride entries per particle) through `scratch`, which swaps with a. A
// scratch that lives on (the other history buffer) spares the page faults of a fresh large
// one at each rebuild: 0.7 ms of a 0.9 ms sort for the wall history of 8,000 spheres.
template <class T>
void permute(std::vector<T>& a, const std::vector<std::int32_t>& order, std::size_t stride,
             std::vector<T>& scratch) {
  if (a.empty()) return;
  scratch.resize(a.size());
  for (std::size_t i = 0; i < order.size(); ++i)
    std::copy_n(a.begin() + static_cast<std::ptrdiff_t>(order[i] * stride), stride,
                scratch.begin() + static_cast<std::ptrdiff_t>(i * stride));
  a.swap(scratch);
}
template <class T>
void permute(std::vector<T>& a, const std::vector<std::int32_t>& order) {
  std::vector<T> scratch;
  permute(a, order, 1, scratch);
}

// A pass's blocks shared out among the threads. Each thread owns a contiguous share, the same
// every step (its particles stay in its core's cache), and takes its blocks from the front; a
// thread that has run out takes the others' from the back, so that neither an uneven share
// (the pile's blocks have more contacts) nor a thread delayed by the machine holds the other
// at the barrier. Which thread runs a block does not change the results.
class BlockShares {
 public:
  BlockShares() = default;
  explicit BlockShares(int threads)
      : threads_(threads), shares_(new Share[static_cast<std::size_t>(threads)]) {}
  void reset(int blocks) {  // before the parallel region
    for (int t = 0; t < threads_; ++t)
      shares_[t].range.store(pack(t * blocks / threads_, (t + 1) * blocks / threads_),
                             std::memory_order_relaxed);
  }
  // f(b) for the blocks that thread t takes.
  template <class F>
  void run(int t, F&& f) {
    int b;
    while (take(shares_[t], true, b)) f(b);
    for (int v = 1; v < threads_; ++v)
      while (take(shares_[(t + v) % threads_], false, b)) f(b);
  }

 private:
  struct alignas(64) Share {  // a cache line each: the owners update them at every block
    std::atomic<std::uint64_t> range{0};  // blocks [front, back), front in the low 32 bits
  };
  static std::uint64_t pack(int front, int back) {
    return static_cast<std::uint64_t>(front) | static_cast<std::uint64_t>(back) << 32;
  }
  static bool take(Share& s, bool front, int& b) {
    std::uint64_t r = s.range.load(std::memory_order_relaxed);
    for (;;) {
      const int lo = static_cast<int>(r & 0xffffffffu), hi = static_cast<int>(r >> 32);
      if (lo >= hi) return false;
      // Relaxed: the barriers around the passes order the blocks' data.
      if (s.range.compare_exchange_weak(r, front ? pack(lo + 1, hi) : pack(lo, hi - 1),
                                        std::memory_order_relaxed)) {
        b = front ? lo : hi - 1;
        return true;
      }
    }
  }
  int threads_ = 0;
  std::unique_ptr<Share[]> shares_;
};

class CpuEngine final : public EngineCore<CpuArray> {
 public:
  CpuEngine(const EngineConfig& c, CpuStep step, std::unique_ptr<NonsmoothStep> nonsmooth = {})
      : EngineCore(c, step.variant), step_(std::move(step)), nonsmooth_(std::move(nonsmooth)) {
    threads_ = c.threads > 0 ? c.threads : omp_get_max_threads();
    pair_shares_ = BlockShares(threads_);
    particle_shares_ = BlockShares(threads_);
    const std::size_t n = static_cast<std::size_t>(count_);
    for (auto* a : state_[0].all) a->assign(n, 0.0);
    if (c.recompute)  // the back buffer
      for (auto* a : state_[1].all) a->assign(n, 0.0);
    radius_ = c.radius;
    set_mass_properties();
    id_.resize(n);
    std::iota(id_.begin(), id_.end(), 0);
    set_particles(c.particles);
    place_mesh([](const auto& host, auto& array) { array = host; }, true);
  }

  const StepTotals& compute(const ContainerKinematics& container, double dt) override {
    if (needs_rebuild_) rebuild(container);
    dt_ = dt;
    const ParticleStepArgs a = args(container, dt);
    if (nonsmooth_) {
      totals_ = StepTotals{};
      nonsmooth_->step(a, threads_, totals_);
      flag_non_finite(totals_);
      return totals_;
    }
    const ClearanceSkip skip{travel_, expiry_.data(), sizes_.r_max};
    const LoadArrays load{loads_[0].data(), loads_[1].data(), loads_[2].data(),
                          loads_[3].data(), loads_[4].data(), loads_[5].data()};
    const int blocks = (count_ + kBlock - 1) / kBlock;
    block_totals_.assign(static_cast<std::size_t>(blocks), StepTotals{});
    auto range = [&](int b) {
      return std::make_pair(b * kBlock, std::min(count_, (b + 1) * kBlock));
    };
    // Each thread lists its blocks' contacts in its own batch.
    auto pair_block = [&](int b, ContactBatch& batch) {
      const auto [begin, end] = range(b);
      step_.pair_block(begin, end, a, skip, load, batch,
                       block_totals_[static_cast<std::size_t>(b)]);
    };
    auto particle_block = [&](int b, ContactBatch& batch) {
      const auto [begin, end] = range(b);
      step_.particle_block(begin, end, a, load, batch, block_totals_[static_cast<std::size_t>(b)]);
    };
    if (blocks == 1 || threads_ == 1) {
      // Small scenes: a parallel region would cost more than it saves. In one thread, a
      // block's particle pass can follow its pair pass while the block is in cache: a
      // particle's pairs are computed by itself and its lower partners, all done by then
      // (+3.5 % at 8,000 spheres). Across threads the blocks waiting for another thread's
      // pairs cost more than that (measured -5 % on 2 threads), so they keep two passes.
      for (int b = 0; b < blocks; ++b) {
        pair_block(b, batches_[0]);
        particle_block(b, batches_[0]);
      }
    } else {
      pair_shares_.reset(blocks);
      particle_shares_.reset(blocks);
#pragma omp parallel num_threads(threads_)
      {
        const int t = omp_get_thread_num();
        ContactBatch& batch = batches_[static_cast<std::size_t>(t)];
        pair_shares_.run(t, [&](int b) { pair_block(b, batch); });
#pragma omp barrier
        particle_shares_.run(t, [&](int b) { particle_block(b, batch); });
      }
    }
    totals_ = StepTotals{};
    for (const auto& t : block_totals_) accumulate(totals_, t);
    flag_non_finite(totals_);
    return totals_;
  }

  void accept() override {
    if (config_.recompute) current_ ^= 1, history_current_ ^= 1;  // the back buffers
    track_drift(totals_);
  }

  std::string backend() const override {
    return "cpu (" + std::to_string(threads_) + " thread" + (threads_ > 1 ? "s)" : ")");
  }
  int threads() const override {
    return threads_;
  }

  std::vector<ParticleState> particles() const override {
    const State& s = state_[current_];
    std::vector<ParticleState> out(static_cast<std::size_t>(count_));
    for (std::size_t i = 0; i < out.size(); ++i)
      out[static_cast<std::size_t>(id_[i])] = {
          {s.x[i], s.y[i], s.z[i]}, {s.vx[i], s.vy[i], s.vz[i]}, {s.wx[i], s.wy[i], s.wz[i]}};
    return out;
  }

  void set_particles(const std::vector<ParticleState>& p) override {
    State& s = state_[current_];
    for (std::size_t i = 0; i < p.size(); ++i) {
      const ParticleState& q = p[static_cast<std::size_t>(id_[i])];
      s.x[i] = q.position.x, s.y[i] = q.position.y, s.z[i] = q.position.z;
      s.vx[i] = q.velocity.x, s.vy[i] = q.velocity.y, s.vz[i] = q.velocity.z;
      s.wx[i] = q.spin.x, s.wy[i] = q.spin.y, s.wz[i] = q.spin.z;
    }
    const std::size_t n = static_cast<std::size_t>(count_);
    for (auto& h : history_) {
      h.neighbour.clear();
      h.neighbour_mask.assign(n, 0);
      h.wall.assign(variant_.history ? 3 * kWallSlots * n : 0, 0.0);
      h.wall_mask.assign(n, 0);
      h.wall_key.assign(keyed_history() ? kWallSlots * n : 0, 0);
    }
    neighbours_.clear();
    partner_id_.clear();
    reverse_.clear();
    neighbour_count_.assign(n, 0);
    reverse_count_.assign(n, 0);
    slot_start_.assign(n + 1, 0);
    reverse_start_.assign(n + 1, 0);
    incoming_.assign(n, 0);
    expiry_.assign(n, 0.0);
    for (auto& component : loads_) component.assign(n, 0.0);
    needs_rebuild_ = true;
  }

  // The lists from the compact layout to the checkpoint's.
  StateArrays save() const override {
    EngineCheckpoint c;
    const State& s = state_[current_];
    const auto columns = state_columns(c);
    for (int k = 0; k < 9; ++k) *columns[k] = *s.all[k];
    c.id = id_;
    c.radius = radius_;
    const History& h = history_[history_current_];
    const std::size_t slots = static_cast<std::size_t>(count_) * max_neighbours_;
    c.neighbours.assign(slots, -1);
    c.partner_id.assign(slots, -1);
    c.reverse.assign(slots, -1);
    c.history.assign(variant_.history ? 3 * slots : 0, 0.0);
    for (int i = 0; i < count_; ++i) {
      const std::size_t to = static_cast<std::size_t>(i) * max_neighbours_;
      const int from = slot_start_[i], n = neighbour_count_[i];
      // data() + offset: the lists are empty before the first build.
      std::copy_n(neighbours_.data() + from, padded(n), c.neighbours.data() + to);
      std::copy_n(partner_id_.data() + from, n, c.partner_id.data() + to);
      std::copy_n(reverse_.data() + reverse_start_[i], reverse_count_[i], c.reverse.data() + to);
      if (variant_.history)
        std::copy_n(h.neighbour.data() + 3 * static_cast<std::size_t>(from), 3 * n,
                    c.history.data() + 3 * to);
    }
    c.wall_history = h.wall;
    c.wall_mask = h.wall_mask;
    c.wall_key = h.wall_key;
    c.neighbour_mask = h.neighbour_mask;
    c.neighbour_count = neighbour_count_;
    c.reverse_count = reverse_count_;
    save_grid(c);
    return to_arrays(std::move(c));
  }

  // The lists from the checkpoint's layout to the compact one.
  void restore(const StateArrays& in) override {
    EngineCheckpoint c = from_arrays(in, count_, variant_.history, keyed_history());
    set_particles(config_.particles);  // clears the lists
    restore_grid(c);
    State& s = state_[current_];
    const auto columns = state_columns(c);
    for (int k = 0; k < 9; ++k) *s.all[k] = std::move(*columns[k]);
    id_ = std::move(c.id);
    radius_ = std::move(c.radius);
    set_mass_properties();
    History& h = history_[history_current_];
    h.wall = std::move(c.wall_history);
    h.wall_mask = std::move(c.wall_mask);
    h.wall_key = std::move(c.wall_key);
    h.neighbour_mask = std::move(c.neighbour_mask);
    neighbour_count_ = std::move(c.neighbour_count);
    reverse_count_ = std::move(c.reverse_count);
    set_slot_starts();
    set_reverse_starts();
    for (int i = 0; i < count_; ++i) {
      const std::size_t from = static_cast<std::size_t>(i) * max_neighbours_;
      const int to = slot_start_[i], n = neighbour_count_[i];
      std::copy_n(c.neighbours.data() + from, padded(n), neighbours_.data() + to);
      std::copy_n(c.partner_id.data() + from, n, partner_id_.data() + to);
      std::copy_n(c.reverse.data() + from, reverse_count_[i], reverse_.data() + reverse_start_[i]);
      if (variant_.history)
        std::copy_n(c.history.data() + 3 * from, 3 * n,
                    h.neighbour.data() + 3 * static_cast<std::size_t>(to));
    }
  }

  // Memory held now: the lists take what the last build needed (nothing before the first step).
  std::size_t bytes_per_particle() const override {
    auto bytes = [](const auto& v) { return v.capacity() * sizeof(v[0]); };
    std::size_t sum = pair_capacity_ * variant_.pair_doubles * sizeof(double) + bytes(radius_) +
                      bytes(inv_mass_) + bytes(inv_inertia_) + bytes(incoming_) + bytes(expiry_);
    for (const auto& component : loads_) sum += bytes(component);
    for (const auto& s : state_)
      for (const auto* a : s.all) sum += bytes(*a);
    for (const auto& h : history_)
      sum += bytes(h.neighbour) + bytes(h.wall) + bytes(h.neighbour_mask) + bytes(h.wall_mask) +
             bytes(h.wall_key);
    for (const auto& batch : batches_) sum += batch.bytes();
    for (const auto* a : {&id_, &neighbours_, &partner_id_, &neighbour_count_, &slot_start_,
                          &reverse_, &reverse_count_, &reverse_start_})
      sum += bytes(*a);
    return sum / static_cast<std::size_t>(count_);
  }

 private:
  void set_mass_properties() {
    MassProperties m = mass_properties(radius_);
    inv_mass_ = std::move(m.inv_mass);
    inv_inertia_ = std::move(m.inv_inertia);
  }

  ParticleStepArgs args(const ContainerKinematics& container, double dt) {
    // In place without recompute. Only the particle pass writes the state, each particle its
    // own. On several threads a barrier separates it from the pair pass; on one, a block's
    // particle pass follows its pairs, and later pairs read only particles of higher index.
    // Likewise the tangential history: each slot is read and then rewritten by its one
    // contact, so only a step that may be recomputed needs a second buffer (in place: +5 to
    // +10 % at 8,000 spheres, the history's cache traffic halved).
    const int back = config_.recompute ? 1 : 0;
    return step_args(container, dt, state_[current_], state_[current_ ^ back],
                     history_[history_current_], history_[history_current_ ^ back],
                     pair_load_.get());
  }

  // Sorts the particles by grid cell and rebuilds the neighbour lists, carrying the history.
  void rebuild(const ContainerKinematics& container) {
    const std::size_t n = static_cast<std::size_t>(count_);
    State& s = state_[current_];
    grid_ = rebuild_grid(container);
    const CellOrder sorted = sort_by_cell(grid_, n, [&](std::size_t i) {
      return Vec3{s.x[i], s.y[i], s.z[i]};
    });
    const std::vector<std::int32_t>& order = sorted.order;
    const std::vector<std::int32_t>& cell_start = sorted.cell_start;
    for (auto* a : s.all) permute(*a, order);
    permute(id_, order);
    permute(radius_, order);
    permute(inv_mass_, order);
    permute(inv_inertia_, order);
    if (!mesh_memo_.empty()) {  // the memos follow their particles
      permute(mesh_memo_, order, kMemoInts, memo_scratch_);
      permute(mesh_memo_at_, order, 4, memo_at_scratch_);
      scene_args_.geometry.mesh.memo = mesh_memo_.data();
      scene_args_.geometry.mesh.memo_at = mesh_memo_at_.data();
    }
    History& hin = history_[history_current_];
    History& scratch = history_[history_current_ ^ 1];
    // Through the other history buffer: a scratch, or the back buffer that the next step
    // rewrites (masks whole, history where live).
    permute(hin.wall, order, 3 * kWallSlots, scratch.wall);
    permute(hin.wall_mask, order, 1, scratch.wall_mask);
    permute(hin.wall_key, order, kWallSlots, scratch.wall_key);

    // The lists are compact: counted first (no lists to write into), then written from their
    // starts.
    NeighbourBuildArgs b = build_args(s, cell_start.data(), cell_start.data() + 1);
    b.neighbours = b.partner_id = b.reverse = nullptr;
    const std::vector<std::int32_t> old_start = slot_start_, old_partner = partner_id_,
                                    old_count = neighbour_count_;
    bool fits = for_all([&](int i) { return build_neighbours_of(i, b); });
    set_slot_starts();
    carry_history(b, order.data(), old_start.data(), old_partner.data(), old_count.data(), hin,
                  scratch);
    b.neighbours = neighbours_.data();
    b.partner_id = partner_id_.data();
    fits &= for_all([&](int i) { return build_neighbours_of(i, b); });
    fits &= build_reverse_lists(b);  // counts
    set_reverse_starts();
    b.reverse = reverse_.data();
    build_reverse_lists(b);
    if (!fits) throw SimulationError(neighbour_overflow_message(max_neighbours_));
    if (variant_.history) {
      std::swap(hin.neighbour, scratch.neighbour);
      std::swap(hin.neighbour_mask, scratch.neighbour_mask);
    }
    travel_ = 0;
    std::fill(expiry_.begin(), expiry_.end(), 0.0);  // new partners: test every particle
    needs_rebuild_ = false;
  }

  // Whether f(i) holds for every particle, f run over the threads.
  template <class F>
  bool for_all(F&& f) {
    int failed = 0;
#pragma omp parallel for num_threads(threads_) schedule(static) reduction(| : failed)
    for (int i = 0; i < count_; ++i) failed |= f(i) ? 0 : 1;
    return !failed;
  }

  // Compact forward lists: starts from the (padded) counts, and room for their slots. The
  // arrays only grow, so that the old history stays intact while the new lists are written.
  void set_slot_starts() {
    for (int i = 0; i < count_; ++i)
      slot_start_[i + 1] = slot_start_[i] + padded(neighbour_count_[i]);
    const auto slots = static_cast<std::size_t>(slot_start_[count_]);
    // A block lists at most its slots' pairs and kMaxWallContacts walls per particle.
    std::size_t block_slots = 0;
    for (int b = 0; b < count_; b += kBlock)
      block_slots = std::max<std::size_t>(
          block_slots, slot_start_[std::min(count_, b + kBlock)] - slot_start_[b]);
    batches_.resize(static_cast<std::size_t>(threads_));
    for (auto& batch : batches_)
      if (batch.particle.size() < block_slots + kLanes || batch.gap.empty())  // + padding
        batch.resize(block_slots + block_slots / 4,
                     static_cast<std::size_t>(std::min(count_, kBlock)) * kMaxWallContacts);
    grow(neighbours_, slots);
    grow(partner_id_, slots);
    if (variant_.history)
      for (auto& h : history_) grow(h.neighbour, 3 * slots);
    if (slots > pair_capacity_) {
      // Written before it is read, and only for pairs in contact: left uninitialised.
      pair_capacity_ = slots + slots / 4;
      pair_load_.reset(new double[variant_.pair_doubles * pair_capacity_]);
    }
  }
  void set_reverse_starts() {
    for (int i = 0; i < count_; ++i) reverse_start_[i + 1] = reverse_start_[i] + reverse_count_[i];
    grow(reverse_, static_cast<std::size_t>(reverse_start_[count_]));
  }
  template <class T>
  static void grow(std::vector<T>& v, std::size_t size) {
    if (v.size() < size) v.resize(size);
  }

  CpuStep step_;
  std::unique_ptr<NonsmoothStep> nonsmooth_;  // a non-smooth scene's step, instead of step_
  int threads_ = 1;
  int current_ = 0, history_current_ = 0;  // the front buffers
  std::vector<double> expiry_;             // ClearanceSkip, per particle
  std::vector<double> loads_[6];           // LoadArrays
  std::unique_ptr<double[]> pair_load_;
  std::size_t pair_capacity_ = 0;  // slots pair_load_ holds
  std::vector<StepTotals> block_totals_;
  std::vector<ContactBatch> batches_;       // one per thread
  std::vector<std::int32_t> memo_scratch_;  // permute()'s, for the mesh memos
  std::vector<double> memo_at_scratch_;
  BlockShares pair_shares_, particle_shares_;
};

}  // namespace
}  // namespace cpu_engine

namespace {

using CpuStepOf = cpu_engine::CpuStep (*)(const EngineConfig&);

struct PickStepOf {
  template <class N, class T, bool R>
  CpuStepOf operator()() const {
    return &cpu_step_of<N, T, R>;
  }
};

struct NameOf {
  template <class V>
  std::string operator()() const {
    return variant_string<V>();
  }
};

}  // namespace

std::unique_ptr<DemEngine> make_cpu_engine(const EngineConfig& config) {
  if (config.nonsmooth) {
    cpu_engine::NonsmoothVariant v = cpu_engine::make_nonsmooth_step(config);
    return std::make_unique<cpu_engine::CpuEngine>(
        config, cpu_engine::CpuStep{nullptr, nullptr, std::move(v.variant)}, std::move(v.step));
  }
  return std::make_unique<cpu_engine::CpuEngine>(config,
                                                 dispatch_laws(config, PickStepOf{})(config));
}

std::string variant_name(const EngineConfig& config) {
  if (config.nonsmooth) return cpu_engine::make_nonsmooth_step(config).variant.name;
  return dispatch_variant(config, NameOf{});
}

#ifndef PDSIM_HAVE_CUDA
bool cuda_device_available(std::string* description) {
  if (description) *description = "this pdsim was built without CUDA";
  return false;
}
#endif

std::unique_ptr<DemEngine> make_engine(const EngineConfig& config) {
  if (config.backend == Backend::cuda) {
#ifdef PDSIM_HAVE_CUDA
    if (!cuda_device_available())
      throw InputError("solver.backend = \"cuda\" but no CUDA device is available");
    if (config.nonsmooth)
      throw InputError(
          "contact.model = \"nonsmooth\" runs on the CPU backend only (solver.backend = "
          "\"cpu\"); the CUDA engine has the penalty laws");
    return make_cuda_engine(config);
#else
    throw InputError("solver.backend = \"cuda\" but this pdsim was built without CUDA");
#endif
  }
  return make_cpu_engine(config);
}

}  // namespace pdsim
