// The GPU engine's orchestration, written once for an execution policy `Exec`: CudaExec
// (kernels/cuda/engine_cuda.cu) launches each pass as a kernel with one thread per particle;
// HostExec (kernels/gpu_engine_host.hpp) runs the same passes in the same order on the host, so
// that CI tests the logic the GPU runs. The passes are the shared per-particle functions
// (kernels/particle_step.hpp, kernels/neighbours.hpp) on fixed-stride lists: particle i's slots
// start at i * max_neighbours. Totals are reduced per block of kBlock particles in a fixed tree
// order, then over the blocks in a fixed order, so two runs are bitwise identical.
//
// What Exec provides:
//   Array<T>         owns one buffer: resize (drops the contents), data, size, bytes, swap,
//                    fill_bytes(byte, exec), upload(host, exec, name), download(exec)
//   name()           "cuda (H100)", "host reference"
//   each(n, f, what) f(i) for every i < n, as one launch
//   sort_pairs(...)  stable sort of (key, value) by the key's low end_bit bits
//   step<V>          the variant's pair and particle passes with their block sums
//   sum_blocks(...)  the block totals summed in a fixed order, the overflow flag added; waits
//   synchronize()    waits for the queued work
#pragma once

#include <algorithm>
#include <numeric>
#include <string>
#include <utility>
#include <vector>

#include "kernels/engine.hpp"
#include "kernels/variant_dispatch.hpp"

namespace pdsim {
namespace gpu_engine {

constexpr int kBlock = 256;  // particles per reduction block (threads per CUDA block)

inline int blocks_for(int count) {
  return (count + kBlock - 1) / kBlock;
}

// The block reduction's fixed pairing: part[t] += part[t + stride] for t < stride, the stride
// halving from kBlock / 2. A GPU block runs each level's additions at once, the host one by one:
// the same sums in the same order.
PDSIM_HD void reduce_level(ParticleContribution* part, int t, int stride) {
  if (t < stride) accumulate(part[t], part[t + stride]);
}

// ---- the rebuild's passes, one call per particle ------------------------------------------------

struct CellKeys {
  int count;
  Grid grid;
  const double *x, *y, *z;
  std::uint32_t* cell;
  std::int32_t* index;
  PDSIM_HD void operator()(int i) const {
    cell[i] = static_cast<std::uint32_t>(cell_of(grid, {x[i], y[i], z[i]}));
    index[i] = i;
  }
};

// Per-particle arrays that move with the particles when they are reordered by cell.
constexpr int kGatheredColumns = 12;  // x y z vx vy vz wx wy wz radius inv_mass inv_inertia
struct Gather {
  const std::int32_t* order;  // new index -> old index
  const double* column_in[kGatheredColumns];
  double* column_out[kGatheredColumns];
  const std::int32_t* id_in;
  std::int32_t* id_out;
  const double* wall_history_in;  // nullptr when the scene has no tangential history
  double* wall_history_out;
  const std::uint8_t* wall_mask_in;
  std::uint8_t* wall_mask_out;
  PDSIM_HD void operator()(int i) const {
    const int from = order[i];
    for (int c = 0; c < kGatheredColumns; ++c) column_out[c][i] = column_in[c][from];
    id_out[i] = id_in[from];
    if (wall_history_in) {
      for (int s = 0; s < 3 * kWallSlots; ++s)
        wall_history_out[3 * kWallSlots * i + s] = wall_history_in[3 * kWallSlots * from + s];
      wall_mask_out[i] = wall_mask_in[from];
    }
  }
};

// Cells start and end where the sorted cell index changes; empty cells keep start = end = 0.
struct CellRanges {
  int count;
  const std::uint32_t* sorted_cell;
  std::int32_t *cell_start, *cell_end;
  PDSIM_HD void operator()(int i) const {
    const std::uint32_t c = sorted_cell[i];
    if (i == 0 || sorted_cell[i - 1] != c) cell_start[c] = i;
    if (i == count - 1 || sorted_cell[i + 1] != c) cell_end[c] = i + 1;
  }
};

struct BuildNeighbours {
  NeighbourBuildArgs args;
  int* overflow;
  PDSIM_HD void operator()(int i) const {
    if (!build_neighbours_of(i, args)) *overflow = 1;
  }
};

// After BuildNeighbours (it reads every forward list).
struct BuildReverse {
  NeighbourBuildArgs args;
  int* overflow;
  PDSIM_HD void operator()(int i) const {
    if (!build_reverse_of(i, args)) *overflow = 1;
  }
};

// ---- the engine ---------------------------------------------------------------------------------

template <class Exec>
class GpuEngine final : public DemEngine {
  template <class T>
  using Array = typename Exec::template Array<T>;

  struct State {
    Array<double> x, y, z, vx, vy, vz, wx, wy, wz;
    Array<double>* all[9] = {&x, &y, &z, &vx, &vy, &vz, &wx, &wy, &wz};
    ParticleArrays view() const {
      return {x.data(),  y.data(),  z.data(),  vx.data(), vy.data(),
              vz.data(), wx.data(), wy.data(), wz.data()};
    }
  };
  struct History {
    Array<double> neighbour, wall;
    Array<std::uint64_t> neighbour_mask;
    Array<std::uint8_t> wall_mask;
  };

 public:
  // What is compiled per kernel variant: its two passes and block sums (Exec::step<V>).
  using StepFn = void (*)(const ParticleStepArgs&, ParticleContribution* block_totals, int blocks,
                          const Exec&);
  struct Step {
    StepFn run;
    VariantInfo variant;
  };
  template <class V>
  static Step step_of() {
    return {&Exec::template step<V>, variant_info<V>()};
  }
  struct PickStep {  // for dispatch_variant()
    template <class V>
    Step operator()() const {
      return step_of<V>();
    }
  };

  GpuEngine(const EngineConfig& c, Step step)
      : config_(c), sizes_(engine_sizes(c)), step_(step.run), variant_(std::move(step.variant)) {
    count_ = sizes_.count;
    max_neighbours_ = sizes_.max_neighbours;
    const std::size_t n = static_cast<std::size_t>(count_);
    for (auto& s : state_)
      for (auto* a : s.all) a->resize(n);
    for (auto* a :
         {&radius_, &inv_mass_, &inv_inertia_, &radius_next_, &inv_mass_next_, &inv_inertia_next_})
      a->resize(n);
    for (auto* a : {&id_, &id_next_, &order_in_, &order_}) a->resize(n);
    cell_key_.resize(n);
    cell_key_sorted_.resize(n);
    block_totals_.resize(static_cast<std::size_t>(blocks_for(count_)));
    overflow_.resize(1);
    overflow_.fill_bytes(0, exec_);

    radius_host_ = c.radius;
    upload_particle_constants();
    std::vector<std::int32_t> id(n);
    std::iota(id.begin(), id.end(), 0);
    id_.upload(id, exec_, "id");
    size_neighbour_arrays();
    set_particles(c.particles);
  }

  const StepTotals& compute(const ContainerKinematics& container, double dt) override {
    if (needs_rebuild_) rebuild(container);
    dt_ = dt;
    const int blocks = blocks_for(count_);
    step_(args(container, dt), block_totals_.data(), blocks, exec_);
    totals_ = exec_.sum_blocks(block_totals_.data(), blocks, overflow_.data());
    if (totals_.flags & kNeighbourOverflow)
      throw SimulationError(neighbour_overflow_message(max_neighbours_));
    return totals_;
  }

  void accept() override {
    current_ ^= 1;
    if (lists_expired(travel_, totals_.speed_sq, dt_, sizes_.skin)) needs_rebuild_ = true;
  }

  int count() const override { return count_; }
  std::string variant() const override { return variant_.name; }
  std::string backend() const override { return exec_.name(); }
  int threads() const override {
    return 1;  // host threads; the device work is one thread per particle
  }

  std::vector<ParticleState> particles() const override {
    const State& s = state_[current_];
    std::vector<std::vector<double>> c;
    for (const auto* a : s.all) c.push_back(a->download(exec_));
    const std::vector<std::int32_t> id = id_.download(exec_);
    std::vector<ParticleState> out(static_cast<std::size_t>(count_));
    for (std::size_t i = 0; i < out.size(); ++i)
      out[static_cast<std::size_t>(id[i])] = {
          {c[0][i], c[1][i], c[2][i]}, {c[3][i], c[4][i], c[5][i]}, {c[6][i], c[7][i], c[8][i]}};
    return out;
  }

  void set_particles(const std::vector<ParticleState>& p) override {
    if (p.size() != static_cast<std::size_t>(count_))
      throw SimulationError("set_particles: " + std::to_string(p.size()) +
                            " particles given, the engine has " + std::to_string(count_));
    const std::vector<std::int32_t> id = id_.download(exec_);
    std::vector<std::vector<double>> c(9, std::vector<double>(p.size()));
    for (std::size_t i = 0; i < p.size(); ++i) {
      const ParticleState& q = p[static_cast<std::size_t>(id[i])];
      const double values[9] = {q.position.x, q.position.y, q.position.z,
                                q.velocity.x, q.velocity.y, q.velocity.z,
                                q.spin.x,     q.spin.y,     q.spin.z};
      for (int k = 0; k < 9; ++k) c[static_cast<std::size_t>(k)][i] = values[k];
    }
    State& s = state_[current_];
    for (int k = 0; k < 9; ++k)
      s.all[k]->upload(c[static_cast<std::size_t>(k)], exec_, kStateNames[k]);
    clear_history();
    exec_.synchronize();  // the uploads read host memory that is about to go away
    needs_rebuild_ = true;
  }

  StateArrays save() const override {
    StateArrays out;
    const State& s = state_[current_];
    for (int k = 0; k < 9; ++k) out[kStateNames[k]] = s.all[k]->download(exec_);
    out["id"] = id_.download(exec_);
    out["radius"] = radius_.download(exec_);
    const History& h = history_[current_];
    std::vector<std::uint64_t> neighbour_mask = h.neighbour_mask.download(exec_);
    std::vector<std::uint8_t> wall_mask = h.wall_mask.download(exec_);
    out["history"] = live_history(h.neighbour.download(exec_), neighbour_mask, max_neighbours_);
    out["wall_history"] = live_history(h.wall.download(exec_), wall_mask, kWallSlots);
    out["wall_mask"] = std::move(wall_mask);
    out["neighbour_mask"] = std::move(neighbour_mask);
    out["neighbours"] = neighbours_.download(exec_);
    out["partner_id"] = partner_id_.download(exec_);
    out["neighbour_count"] = neighbour_count_.download(exec_);
    out["reverse"] = flat_reverse(reverse_.download(exec_), max_neighbours_);
    out["reverse_count"] = reverse_count_.download(exec_);
    put_grid(out, {grid_, needs_rebuild_, max_neighbours_, travel_});
    return out;
  }

  void restore(const StateArrays& in) override {
    const GridState g = check_checkpoint(in, count_, variant_.history);
    max_neighbours_ = g.max_neighbours;
    size_neighbour_arrays();
    State& s = state_[current_];
    for (int k = 0; k < 9; ++k)
      s.all[k]->upload(state_values<double>(in, kStateNames[k]), exec_, kStateNames[k]);
    id_.upload(state_values<std::int32_t>(in, "id"), exec_, "id");
    radius_host_ = state_values<double>(in, "radius");
    upload_particle_constants();
    clear_history();
    History& h = history_[current_];
    h.neighbour.upload(state_values<double>(in, "history"), exec_, "history");
    h.wall.upload(state_values<double>(in, "wall_history"), exec_, "wall_history");
    h.wall_mask.upload(state_values<std::uint8_t>(in, "wall_mask"), exec_, "wall_mask");
    h.neighbour_mask.upload(state_values<std::uint64_t>(in, "neighbour_mask"), exec_,
                            "neighbour_mask");
    neighbours_.upload(state_values<std::int32_t>(in, "neighbours"), exec_, "neighbours");
    partner_id_.upload(state_values<std::int32_t>(in, "partner_id"), exec_, "partner_id");
    neighbour_count_.upload(state_values<std::int32_t>(in, "neighbour_count"), exec_,
                            "neighbour_count");
    const std::vector<std::int32_t> reverse =
        packed_reverse(state_values<std::int32_t>(in, "reverse"), max_neighbours_);
    reverse_.upload(reverse, exec_, "reverse");
    reverse_count_.upload(state_values<std::int32_t>(in, "reverse_count"), exec_, "reverse_count");
    needs_rebuild_ = g.needs_rebuild;
    overflow_.fill_bytes(0, exec_);
    travel_ = g.travel;
    grid_ = g.grid;
    exec_.synchronize();  // the uploads read host memory that is about to go away
  }

  std::size_t bytes_per_particle() const override {
    std::size_t bytes = 0;
    for (const auto& s : state_)
      for (const auto* a : s.all) bytes += a->bytes();
    for (const auto& h : history_)
      bytes +=
          h.neighbour.bytes() + h.wall.bytes() + h.neighbour_mask.bytes() + h.wall_mask.bytes();
    for (const auto* a :
         {&radius_, &inv_mass_, &inv_inertia_, &radius_next_, &inv_mass_next_, &inv_inertia_next_})
      bytes += a->bytes();
    for (const auto* a :
         {&id_, &id_next_, &order_in_, &order_, &neighbours_, &partner_id_, &partner_id_old_,
          &neighbour_count_, &neighbour_count_old_, &reverse_, &reverse_count_, &slot_start_})
      bytes += a->bytes();
    bytes += incoming_.bytes() + pair_load_.bytes();
    bytes += cell_key_.bytes() + cell_key_sorted_.bytes();
    return bytes / static_cast<std::size_t>(count_);
  }

 private:
  // Mass and inertia of solid spheres, computed as in the CPU engine.
  void upload_particle_constants() {
    const std::size_t n = radius_host_.size();
    std::vector<double> inv_mass(n), inv_inertia(n);
    for (std::size_t i = 0; i < n; ++i) {
      const SphereMass m = sphere_mass(radius_host_[i], config_.density);
      inv_mass[i] = m.inv_mass;
      inv_inertia[i] = m.inv_inertia;
    }
    radius_.upload(radius_host_, exec_, "radius");
    inv_mass_.upload(inv_mass, exec_, "inv_mass");
    inv_inertia_.upload(inv_inertia, exec_, "inv_inertia");
    exec_.synchronize();
  }

  void size_neighbour_arrays() {
    const std::size_t n = static_cast<std::size_t>(count_);
    const std::size_t slots = n * static_cast<std::size_t>(max_neighbours_);
    for (auto& h : history_) {
      h.neighbour.resize(variant_.history ? 3 * slots : 0);
      h.neighbour_mask.resize(n);
      h.wall.resize(variant_.history ? 3 * kWallSlots * n : 0);
      h.wall_mask.resize(n);
    }
    for (auto* a : {&neighbours_, &partner_id_, &partner_id_old_, &reverse_}) a->resize(slots);
    neighbour_count_.resize(n);
    neighbour_count_old_.resize(n);
    reverse_count_.resize(n);
    incoming_.resize(n);
    pair_load_.resize(static_cast<std::size_t>(variant_.pair_doubles) * slots);
    // Fixed stride: particle i's lists start at i * max_neighbours (forward and reverse alike).
    std::vector<std::int32_t> start(n + 1);
    for (std::size_t i = 0; i <= n; ++i) start[i] = static_cast<std::int32_t>(i) * max_neighbours_;
    slot_start_.resize(n + 1);
    slot_start_.upload(start, exec_, "slot_start");
    exec_.synchronize();  // `start` is host memory about to go away
  }

  // Forgets all contacts (as the CPU engine's set_particles does).
  void clear_history() {
    for (auto& h : history_) {
      h.neighbour.fill_bytes(0, exec_);
      h.neighbour_mask.fill_bytes(0, exec_);
      h.wall.fill_bytes(0, exec_);
      h.wall_mask.fill_bytes(0, exec_);
    }
    neighbours_.fill_bytes(0xff, exec_);
    partner_id_.fill_bytes(0xff, exec_);
    neighbour_count_.fill_bytes(0, exec_);
    reverse_.fill_bytes(0xff, exec_);
    reverse_count_.fill_bytes(0, exec_);
    incoming_.fill_bytes(0, exec_);
  }

  ParticleStepArgs args(const ContainerKinematics& container, double dt) const {
    const History& hin = history_[current_];
    const History& hout = history_[current_ ^ 1];
    ParticleStepArgs a = scene_args_;
    a.dt = dt;
    a.container = container;
    a.in = state_[current_].view();
    a.out = state_[current_ ^ 1].view();
    a.radius = radius_.data();
    a.inv_mass = inv_mass_.data();
    a.inv_inertia = inv_inertia_.data();
    a.neighbours = neighbours_.data();
    a.neighbour_count = neighbour_count_.data();
    a.reverse = reverse_.data();
    a.reverse_count = reverse_count_.data();
    a.slot_start = slot_start_.data();
    a.reverse_start = slot_start_.data();
    a.history = history_view(hin, hout);
    a.incoming = incoming_.data();
    a.pair_load = pair_load_.data();
    return a;
  }

  // Sorts the particles by grid cell (stable sort of (cell, index): the same order as the CPU's
  // counting sort) and rebuilds the neighbour lists, carrying the history. The reordered state
  // goes to the back buffers, which then become current.
  void rebuild(const ContainerKinematics& container) {
    grid_ = grid_around(container.position,
                        world_half_size(config_.geometry.half_size, config_.orientation),
                        2 * sizes_.r_max + sizes_.skin);
    const int cells = grid_.nx * grid_.ny * grid_.nz;
    cell_start_.resize(static_cast<std::size_t>(cells));
    cell_end_.resize(static_cast<std::size_t>(cells));

    const State& s = state_[current_];
    exec_.each(count_,
               CellKeys{count_, grid_, s.x.data(), s.y.data(), s.z.data(), cell_key_.data(),
                        order_in_.data()},
               "cell keys");
    int end_bit = 1;
    while (end_bit < 32 && (std::uint32_t{1} << end_bit) < static_cast<std::uint32_t>(cells))
      ++end_bit;
    exec_.sort_pairs(cell_key_, cell_key_sorted_, order_in_, order_, count_, end_bit);

    const int next = current_ ^ 1;
    const State& t = state_[next];
    Gather g{};
    g.order = order_.data();
    for (int k = 0; k < 9; ++k) {
      g.column_in[k] = s.all[k]->data();
      g.column_out[k] = t.all[k]->data();
    }
    g.column_in[9] = radius_.data();
    g.column_out[9] = radius_next_.data();
    g.column_in[10] = inv_mass_.data();
    g.column_out[10] = inv_mass_next_.data();
    g.column_in[11] = inv_inertia_.data();
    g.column_out[11] = inv_inertia_next_.data();
    g.id_in = id_.data();
    g.id_out = id_next_.data();
    History& hin = history_[current_];
    History& hnew = history_[next];
    if (variant_.history) {
      g.wall_history_in = hin.wall.data();
      g.wall_history_out = hnew.wall.data();
      g.wall_mask_in = hin.wall_mask.data();
      g.wall_mask_out = hnew.wall_mask.data();
    }
    exec_.each(count_, g, "gather");
    radius_.swap(radius_next_);
    inv_mass_.swap(inv_mass_next_);
    inv_inertia_.swap(inv_inertia_next_);
    id_.swap(id_next_);

    cell_start_.fill_bytes(0, exec_);
    cell_end_.fill_bytes(0, exec_);
    exec_.each(count_,
               CellRanges{count_, cell_key_sorted_.data(), cell_start_.data(), cell_end_.data()},
               "cell ranges");

    partner_id_.swap(partner_id_old_);
    neighbour_count_.swap(neighbour_count_old_);
    NeighbourBuildArgs b{};
    b.count = count_;
    b.grid = grid_;
    b.x = t.x.data();
    b.y = t.y.data();
    b.z = t.z.data();
    b.radius = variant_.polydisperse ? radius_.data() : nullptr;
    b.mono_radius = scene_args_.mono_radius;
    b.skin = sizes_.skin;
    b.cell_start = cell_start_.data();
    b.cell_end = cell_end_.data();
    b.id = id_.data();
    if (variant_.history) {
      b.old_index = order_.data();
      b.old_slot_start = slot_start_.data();
      b.old_partner_id = partner_id_old_.data();
      b.old_neighbour_count = neighbour_count_old_.data();
      b.old_mask = hin.neighbour_mask.data();
      b.old_history = hin.neighbour.data();
      b.new_mask = hnew.neighbour_mask.data();
      b.new_history = hnew.neighbour.data();
    }
    b.max_neighbours = max_neighbours_;
    b.slot_start = slot_start_.data();
    b.reverse_start = slot_start_.data();
    b.neighbours = neighbours_.data();
    b.neighbour_count = neighbour_count_.data();
    b.partner_id = partner_id_.data();
    b.reverse = reverse_.data();
    b.reverse_count = reverse_count_.data();
    overflow_.fill_bytes(0, exec_);
    exec_.each(count_, BuildNeighbours{b, overflow_.data()}, "neighbour lists");
    exec_.each(count_, BuildReverse{b, overflow_.data()}, "reverse lists");

    travel_ = 0;
    current_ = next;
    needs_rebuild_ = false;
  }

  Exec exec_;  // declared before the arrays, so destroyed after them
  EngineConfig config_;
  EngineSizes sizes_;
  ParticleStepArgs scene_args_ = scene_step_args(config_);
  StepFn step_ = nullptr;
  VariantInfo variant_;
  int count_ = 0, max_neighbours_ = 1, current_ = 0;
  double dt_ = 0, travel_ = 0;  // last step size; drift bound since the last build (m)
  std::vector<double> radius_host_;
  State state_[2];
  History history_[2];
  Array<double> radius_, inv_mass_, inv_inertia_;
  Array<double> radius_next_, inv_mass_next_, inv_inertia_next_;  // rebuild scratch
  Array<std::int32_t> id_, id_next_, neighbours_, partner_id_, partner_id_old_;
  Array<std::int32_t> neighbour_count_, neighbour_count_old_, reverse_, reverse_count_;
  Array<std::int32_t> slot_start_;
  Array<std::uint32_t> incoming_;
  Array<double> pair_load_;
  Array<std::uint32_t> cell_key_, cell_key_sorted_;
  Array<std::int32_t> order_in_, order_, cell_start_, cell_end_;
  Array<int> overflow_;
  Array<ParticleContribution> block_totals_;
  Grid grid_{};
  bool needs_rebuild_ = true;
  StepTotals totals_;
};

}  // namespace gpu_engine
}  // namespace pdsim
