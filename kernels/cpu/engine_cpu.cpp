// The CPU engine: particles, neighbour lists, rebuilds and checkpoints, compiled once. Per kernel
// variant only its two passes (CpuStep, engine_cpu.hpp) differ; they are compiled in translation
// units that CMake generates from engine_cpu_variants.cpp.in, one per normal law, tangential law
// and rolling choice, so that the build compiles them in parallel.
#include <omp.h>

#include <algorithm>
#include <atomic>
#include <numeric>

#include "kernels/cpu/engine_cpu.hpp"

namespace pdsim {
namespace cpu_engine {
namespace {

struct StateBuffer {
  std::vector<double> x, y, z, vx, vy, vz, wx, wy, wz;
  std::vector<double>* all[9] = {&x, &y, &z, &vx, &vy, &vz, &wx, &wy, &wz};
  void resize(std::size_t n) {
    for (auto* a : all) a->assign(n, 0.0);
  }
  ParticleArrays view() {
    return {x.data(),  y.data(),  z.data(),  vx.data(), vy.data(),
            vz.data(), wx.data(), wy.data(), wz.data()};
  }
};

struct HistoryBuffer {
  std::vector<double> neighbour, wall;
  std::vector<std::uint64_t> neighbour_mask;
  std::vector<std::uint8_t> wall_mask;
};

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

class CpuEngine final : public DemEngine {
 public:
  CpuEngine(const EngineConfig& c, CpuStep step)
      : config_(c), step_(std::move(step)), sizes_(engine_sizes(c)) {
    count_ = sizes_.count;
    threads_ = c.threads > 0 ? c.threads : omp_get_max_threads();
    pair_shares_ = BlockShares(threads_);
    particle_shares_ = BlockShares(threads_);
    max_neighbours_ = sizes_.max_neighbours;
    const std::size_t n = static_cast<std::size_t>(count_);
    state_[0].resize(n);
    if (c.recompute) state_[1].resize(n);  // the back buffer
    radius_ = c.radius;
    inv_mass_.resize(n);
    inv_inertia_.resize(n);
    set_mass_properties();
    id_.resize(n);
    std::iota(id_.begin(), id_.end(), 0);
    set_particles(c.particles);
  }

  const StepTotals& compute(const ContainerKinematics& container, double dt) override {
    if (needs_rebuild_) rebuild(container);
    dt_ = dt;
    const ParticleStepArgs a = args(container, dt);
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
    if (lists_expired(travel_, totals_.speed_sq, dt_, sizes_.skin)) needs_rebuild_ = true;
  }

  int count() const override {
    return count_;
  }
  std::string variant() const override {
    return step_.variant.name;
  }
  std::string backend() const override {
    return "cpu (" + std::to_string(threads_) + " thread" + (threads_ > 1 ? "s)" : ")");
  }
  int threads() const override {
    return threads_;
  }

  std::vector<ParticleState> particles() const override {
    const StateBuffer& s = state_[current_];
    std::vector<ParticleState> out(static_cast<std::size_t>(count_));
    for (std::size_t i = 0; i < out.size(); ++i)
      out[static_cast<std::size_t>(id_[i])] = {
          {s.x[i], s.y[i], s.z[i]}, {s.vx[i], s.vy[i], s.vz[i]}, {s.wx[i], s.wy[i], s.wz[i]}};
    return out;
  }

  void set_particles(const std::vector<ParticleState>& p) override {
    StateBuffer& s = state_[current_];
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
      h.wall.assign(step_.variant.history ? 3 * kWallSlots * n : 0, 0.0);
      h.wall_mask.assign(n, 0);
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

  StateArrays save() const override {
    StateArrays out;
    const StateBuffer& s = state_[current_];
    for (int k = 0; k < 9; ++k) out[kStateNames[k]] = *s.all[k];
    out["id"] = id_;
    out["radius"] = radius_;
    const HistoryBuffer& h = history_[history_current_];
    // The checkpoint layout: max_neighbours_ slots per particle (see flat_reverse()).
    const std::size_t slots = static_cast<std::size_t>(count_) * max_neighbours_;
    std::vector<std::int32_t> neighbours(slots, -1), partner(slots, -1), reverse(slots, -1);
    std::vector<double> history(step_.variant.history ? 3 * slots : 0, 0.0);
    for (int i = 0; i < count_; ++i) {
      const std::size_t to = static_cast<std::size_t>(i) * max_neighbours_;
      const int from = slot_start_[i], n = neighbour_count_[i];
      std::copy_n(&neighbours_[from], padded(n), &neighbours[to]);
      std::copy_n(&partner_id_[from], n, &partner[to]);
      std::copy_n(&reverse_[reverse_start_[i]], reverse_count_[i], &reverse[to]);
      for (int k = 0; k < n && !history.empty(); ++k)
        if (h.neighbour_mask[i] >> k & 1u)
          std::copy_n(&h.neighbour[3 * (from + k)], 3, &history[3 * (to + k)]);
    }
    out["history"] = std::move(history);
    out["wall_history"] = live_history(h.wall, h.wall_mask, kWallSlots);
    out["wall_mask"] = h.wall_mask;
    out["neighbour_mask"] = h.neighbour_mask;
    out["neighbours"] = std::move(neighbours);
    out["partner_id"] = std::move(partner);
    out["neighbour_count"] = neighbour_count_;
    out["reverse"] = flat_reverse(reverse, max_neighbours_);
    out["reverse_count"] = reverse_count_;
    put_grid(out, {grid_, needs_rebuild_, max_neighbours_, travel_});
    return out;
  }

  void restore(const StateArrays& in) override {
    const GridState g = check_checkpoint(in, count_, step_.variant.history);
    max_neighbours_ = g.max_neighbours;
    set_particles(config_.particles);  // sizes every array for max_neighbours_
    StateBuffer& s = state_[current_];
    for (int k = 0; k < 9; ++k) *s.all[k] = state_values<double>(in, kStateNames[k]);
    id_ = state_values<std::int32_t>(in, "id");
    radius_ = state_values<double>(in, "radius");
    set_mass_properties();
    HistoryBuffer& h = history_[history_current_];
    h.wall = state_values<double>(in, "wall_history");
    h.wall_mask = state_values<std::uint8_t>(in, "wall_mask");
    h.neighbour_mask = state_values<std::uint64_t>(in, "neighbour_mask");
    // From the checkpoint layout (max_neighbours_ slots per particle) to the compact one.
    neighbour_count_ = state_values<std::int32_t>(in, "neighbour_count");
    reverse_count_ = state_values<std::int32_t>(in, "reverse_count");
    const auto& neighbours = state_values<std::int32_t>(in, "neighbours");
    const auto& partner = state_values<std::int32_t>(in, "partner_id");
    const std::vector<std::int32_t> reverse =
        packed_reverse(state_values<std::int32_t>(in, "reverse"), max_neighbours_);
    const std::vector<double>& history = state_values<double>(in, "history");
    set_slot_starts();
    set_reverse_starts();
    for (int i = 0; i < count_; ++i) {
      const std::size_t from = static_cast<std::size_t>(i) * max_neighbours_;
      const int to = slot_start_[i], n = neighbour_count_[i];
      std::copy_n(&neighbours[from], padded(n), &neighbours_[to]);
      std::copy_n(&partner[from], n, &partner_id_[to]);
      std::copy_n(&reverse[from], reverse_count_[i], &reverse_[reverse_start_[i]]);
      if (step_.variant.history) std::copy_n(&history[3 * from], 3 * n, &h.neighbour[3 * to]);
    }
    travel_ = g.travel;
    grid_ = g.grid;
    needs_rebuild_ = g.needs_rebuild;
  }

  // Memory held now: the lists take what the last build needed (nothing before the first step).
  std::size_t bytes_per_particle() const override {
    auto bytes = [](const auto& v) { return v.capacity() * sizeof(v[0]); };
    std::size_t sum = pair_capacity_ * step_.variant.pair_doubles * sizeof(double) +
                      bytes(radius_) + bytes(inv_mass_) + bytes(inv_inertia_) + bytes(incoming_) +
                      bytes(expiry_);
    for (const auto& component : loads_) sum += bytes(component);
    for (const auto& s : state_)
      for (const auto* a : s.all) sum += bytes(*a);
    for (const auto& h : history_)
      sum += bytes(h.neighbour) + bytes(h.wall) + bytes(h.neighbour_mask) + bytes(h.wall_mask);
    for (const auto& batch : batches_) sum += batch.bytes();
    for (const auto* a : {&id_, &neighbours_, &partner_id_, &neighbour_count_, &slot_start_,
                          &reverse_, &reverse_count_, &reverse_start_})
      sum += bytes(*a);
    return sum / static_cast<std::size_t>(count_);
  }

 private:
  void set_mass_properties() {
    for (std::size_t i = 0; i < radius_.size(); ++i) {
      const SphereMass m = sphere_mass(radius_[i], config_.density);
      inv_mass_[i] = m.inv_mass;
      inv_inertia_[i] = m.inv_inertia;
    }
  }

  ParticleStepArgs args(const ContainerKinematics& container, double dt) {
    StateBuffer& in = state_[current_];
    // In place without recompute. Only the particle pass writes the state, each particle its
    // own. On several threads a barrier separates it from the pair pass; on one, a block's
    // particle pass follows its pairs, and later pairs read only particles of higher index.
    StateBuffer& out = state_[config_.recompute ? current_ ^ 1 : current_];
    HistoryBuffer& hin = history_[history_current_];
    // Likewise the tangential history: each slot is read and then rewritten by its one
    // contact, so only a step that may be recomputed needs a second buffer (in place: +5 to
    // +10 % at 8,000 spheres, the history's cache traffic halved).
    HistoryBuffer& hout = config_.recompute ? history_[history_current_ ^ 1] : hin;
    ParticleStepArgs a = scene_args_;
    a.dt = dt;
    a.container = container;
    a.in = in.view();
    a.out = out.view();
    a.radius = radius_.data();
    a.inv_mass = inv_mass_.data();
    a.inv_inertia = inv_inertia_.data();
    a.neighbours = neighbours_.data();
    a.neighbour_count = neighbour_count_.data();
    a.reverse = reverse_.data();
    a.reverse_count = reverse_count_.data();
    a.slot_start = slot_start_.data();
    a.reverse_start = reverse_start_.data();
    a.history = history_view(hin, hout);
    a.incoming = incoming_.data();
    a.pair_load = pair_load_.get();
    return a;
  }

  // Sorts the particles by grid cell and rebuilds the neighbour lists, carrying the history.
  void rebuild(const ContainerKinematics& container) {
    const std::size_t n = static_cast<std::size_t>(count_);
    StateBuffer& s = state_[current_];
    grid_ = grid_around(container.position,
                        world_half_size(config_.geometry.half_size, config_.orientation),
                        2 * sizes_.r_max + sizes_.skin);
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
    HistoryBuffer& hin = history_[history_current_];
    HistoryBuffer& scratch = history_[history_current_ ^ 1];
    // Through the other history buffer: a scratch, or the back buffer that the next step
    // rewrites (masks whole, history where live).
    permute(hin.wall, order, 3 * kWallSlots, scratch.wall);
    permute(hin.wall_mask, order, 1, scratch.wall_mask);

    NeighbourBuildArgs b{};
    b.count = count_;
    b.grid = grid_;
    b.x = s.x.data();
    b.y = s.y.data();
    b.z = s.z.data();
    b.radius = step_.variant.polydisperse ? radius_.data() : nullptr;
    b.mono_radius = radius_[0];
    b.skin = sizes_.skin;
    b.cell_start = cell_start.data();
    b.cell_end = cell_start.data() + 1;
    b.id = id_.data();
    b.max_neighbours = max_neighbours_;
    b.slot_start = slot_start_.data();
    b.reverse_start = reverse_start_.data();
    b.neighbour_count = neighbour_count_.data();
    b.reverse_count = reverse_count_.data();
    const std::vector<std::int32_t> old_start = slot_start_, old_partner = partner_id_,
                                    old_count = neighbour_count_;
    // The lists are compact: counted first, then written from their starts.
    bool fits = for_all([&](int i) { return build_neighbours_of(i, b); });
    set_slot_starts();
    if (step_.variant.history) {
      b.old_index = order.data();
      b.old_slot_start = old_start.data();
      b.old_partner_id = old_partner.data();
      b.old_neighbour_count = old_count.data();
      b.old_mask = hin.neighbour_mask.data();
      b.old_history = hin.neighbour.data();
      b.new_mask = scratch.neighbour_mask.data();
      b.new_history = scratch.neighbour.data();
    }
    b.neighbours = neighbours_.data();
    b.partner_id = partner_id_.data();
    fits &= for_all([&](int i) { return build_neighbours_of(i, b); });
    fits &= build_reverse_lists(b);  // counts
    set_reverse_starts();
    b.reverse = reverse_.data();
    build_reverse_lists(b);
    if (!fits) throw SimulationError(neighbour_overflow_message(max_neighbours_));
    if (step_.variant.history) {
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
    if (step_.variant.history)
      for (auto& h : history_) grow(h.neighbour, 3 * slots);
    if (slots > pair_capacity_) {
      // Written before it is read, and only for pairs in contact: left uninitialised.
      pair_capacity_ = slots + slots / 4;
      pair_load_.reset(new double[step_.variant.pair_doubles * pair_capacity_]);
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

  EngineConfig config_;
  CpuStep step_;
  EngineSizes sizes_;
  ParticleStepArgs scene_args_ = scene_step_args(config_);
  int count_ = 0, threads_ = 1, max_neighbours_ = 1;
  int current_ = 0, history_current_ = 0;  // the front buffers
  double dt_ = 0, travel_ = 0;             // last step size; drift bound since the last build (m)
  std::vector<double> expiry_;             // ClearanceSkip, per particle
  std::vector<double> loads_[6];           // LoadArrays
  StateBuffer state_[2];
  HistoryBuffer history_[2];
  std::vector<double> radius_, inv_mass_, inv_inertia_;
  // Lists in a compact layout: particle i's from slot_start_[i] (reverse_start_[i]).
  std::vector<std::int32_t> id_, neighbours_, partner_id_, neighbour_count_, slot_start_, reverse_,
      reverse_count_, reverse_start_;
  std::vector<std::uint32_t> incoming_;
  std::unique_ptr<double[]> pair_load_;
  std::size_t pair_capacity_ = 0;  // slots pair_load_ holds
  Grid grid_{};
  bool needs_rebuild_ = true;
  std::vector<StepTotals> block_totals_;
  std::vector<ContactBatch> batches_;  // one per thread
  BlockShares pair_shares_, particle_shares_;
  StepTotals totals_;
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
  return std::make_unique<cpu_engine::CpuEngine>(config,
                                                 dispatch_laws(config, PickStepOf{})(config));
}

std::string variant_name(const EngineConfig& config) {
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
    return make_cuda_engine(config);
#else
    throw InputError("solver.backend = \"cuda\" but this pdsim was built without CUDA");
#endif
  }
  return make_cpu_engine(config);
}

}  // namespace pdsim
