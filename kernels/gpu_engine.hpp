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

#include "kernels/engine_core.hpp"

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
  const std::int32_t* wall_key_in;
  std::int32_t* wall_key_out;
  PDSIM_HD void operator()(int i) const {
    const int from = order[i];
    for (int c = 0; c < kGatheredColumns; ++c) column_out[c][i] = column_in[c][from];
    id_out[i] = id_in[from];
    if (wall_history_in) {
      for (int s = 0; s < 3 * kWallSlots; ++s)
        wall_history_out[3 * kWallSlots * i + s] = wall_history_in[3 * kWallSlots * from + s];
      wall_mask_out[i] = wall_mask_in[from];
    }
    if (wall_key_in)  // nullptr unless a mesh's walls keep keyed history
      for (int s = 0; s < kWallSlots; ++s)
        wall_key_out[kWallSlots * i + s] = wall_key_in[kWallSlots * from + s];
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

// The Exec is a base of its own, constructed before the core's arrays and destroyed after them.
template <class Exec>
struct WithExec {
  Exec exec_;
};
template <class Exec>
struct ExecArray {
  template <class T>
  using type = typename Exec::template Array<T>;
};

template <class Exec>
class GpuEngine final : private WithExec<Exec>, public EngineCore<ExecArray<Exec>::template type> {
  using Core = EngineCore<ExecArray<Exec>::template type>;
  template <class T>
  using Array = typename Exec::template Array<T>;
  using Core::config_, Core::variant_, Core::sizes_, Core::scene_args_, Core::count_,
      Core::max_neighbours_, Core::dt_, Core::travel_, Core::grid_, Core::needs_rebuild_,
      Core::totals_, Core::state_, Core::history_, Core::radius_, Core::inv_mass_,
      Core::inv_inertia_, Core::id_, Core::neighbours_, Core::partner_id_, Core::neighbour_count_,
      Core::reverse_, Core::reverse_count_, Core::slot_start_, Core::reverse_start_,
      Core::incoming_;
  using typename Core::History;
  using typename Core::State;
  using WithExec<Exec>::exec_;

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

  GpuEngine(const EngineConfig& c, Step step) : Core(c, step.variant), step_(step.run) {
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

    upload_particle_constants(c.radius);
    std::vector<std::int32_t> id(n);
    std::iota(id.begin(), id.end(), 0);
    id_.upload(id, exec_, "id");
    size_neighbour_arrays();
    set_particles(c.particles);
    this->place_mesh([&](const auto& host, auto& array) {
      array.resize(host.size());
      array.upload(host, exec_, "mesh");
      exec_.synchronize();  // the upload reads host memory that is about to go away
    });
  }

  const StepTotals& compute(const ContainerKinematics& container, double dt) override {
    if (!failure_.empty())
      throw SimulationError("the " + exec_.name() + " engine failed earlier (" + failure_ +
                            ") and cannot go on from its arrays; restore() or set_particles() "
                            "start it again");
    try {
      if (needs_rebuild_) rebuild(container);
      dt_ = dt;
      const int blocks = blocks_for(count_);
      const int next = current_ ^ 1;
      step_(this->step_args(container, dt, state_[current_], state_[next], history_[current_],
                            history_[next], pair_load_.data()),
            block_totals_.data(), blocks, exec_);
      totals_ = exec_.sum_blocks(block_totals_.data(), blocks, overflow_.data());
    } catch (const std::exception& e) {
      // A device reports a kernel's fault at the next wait, by when a rebuild may have swapped
      // half the arrays.
      failure_ = e.what();
      throw;
    }
    if (totals_.flags & kNeighbourOverflow)
      throw SimulationError(neighbour_overflow_message(max_neighbours_));
    return totals_;
  }

  void accept() override {
    current_ ^= 1;
    this->track_drift(totals_);
  }

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
      s.all[k]->upload(c[static_cast<std::size_t>(k)], exec_, "particle state");
    clear_history();
    exec_.synchronize();  // the uploads read host memory that is about to go away
    needs_rebuild_ = true;
    failure_.clear();
  }

  StateArrays save() const override {
    EngineCheckpoint c;
    const State& s = state_[current_];
    const auto columns = state_columns(c);
    for (int k = 0; k < 9; ++k) *columns[k] = s.all[k]->download(exec_);
    c.id = id_.download(exec_);
    c.radius = radius_.download(exec_);
    const History& h = history_[current_];
    c.history = h.neighbour.download(exec_);
    c.wall_history = h.wall.download(exec_);
    c.wall_mask = h.wall_mask.download(exec_);
    c.wall_key = h.wall_key.download(exec_);
    c.neighbour_mask = h.neighbour_mask.download(exec_);
    c.neighbours = neighbours_.download(exec_);
    c.partner_id = partner_id_.download(exec_);
    c.neighbour_count = neighbour_count_.download(exec_);
    c.reverse = reverse_.download(exec_);
    c.reverse_count = reverse_count_.download(exec_);
    this->save_grid(c);
    return to_arrays(std::move(c));
  }

  void restore(const StateArrays& in) override {
    const EngineCheckpoint c = from_arrays(in, count_, variant_.history, this->keyed_history());
    this->restore_grid(c);
    size_neighbour_arrays();
    State& s = state_[current_];
    const auto columns = state_columns(c);
    for (int k = 0; k < 9; ++k) s.all[k]->upload(*columns[k], exec_, "particle state");
    id_.upload(c.id, exec_, "id");
    upload_particle_constants(c.radius);
    clear_history();
    History& h = history_[current_];
    h.neighbour.upload(c.history, exec_, "history");
    h.wall.upload(c.wall_history, exec_, "wall_history");
    h.wall_mask.upload(c.wall_mask, exec_, "wall_mask");
    h.wall_key.upload(c.wall_key, exec_, "wall_key");
    h.neighbour_mask.upload(c.neighbour_mask, exec_, "neighbour_mask");
    neighbours_.upload(c.neighbours, exec_, "neighbours");
    partner_id_.upload(c.partner_id, exec_, "partner_id");
    neighbour_count_.upload(c.neighbour_count, exec_, "neighbour_count");
    reverse_.upload(c.reverse, exec_, "reverse");
    reverse_count_.upload(c.reverse_count, exec_, "reverse_count");
    overflow_.fill_bytes(0, exec_);
    exec_.synchronize();  // the uploads read host memory that is about to go away
    failure_.clear();
  }

  std::size_t bytes_per_particle() const override {
    std::size_t bytes = 0;
    for (const auto& s : state_)
      for (const auto* a : s.all) bytes += a->bytes();
    for (const auto& h : history_)
      bytes += h.neighbour.bytes() + h.wall.bytes() + h.neighbour_mask.bytes() +
               h.wall_mask.bytes() + h.wall_key.bytes();
    for (const auto* a :
         {&radius_, &inv_mass_, &inv_inertia_, &radius_next_, &inv_mass_next_, &inv_inertia_next_})
      bytes += a->bytes();
    for (const auto* a : {&id_, &id_next_, &order_in_, &order_, &neighbours_, &partner_id_,
                          &partner_id_old_, &neighbour_count_, &neighbour_count_old_, &reverse_,
                          &reverse_count_, &slot_start_, &reverse_start_})
      bytes += a->bytes();
    bytes += incoming_.bytes() + pair_load_.bytes();
    bytes += cell_key_.bytes() + cell_key_sorted_.bytes();
    return bytes / static_cast<std::size_t>(count_);
  }

 private:
  void upload_particle_constants(const std::vector<double>& radius) {
    const auto m = this->mass_properties(radius);
    radius_.upload(radius, exec_, "radius");
    inv_mass_.upload(m.inv_mass, exec_, "inv_mass");
    inv_inertia_.upload(m.inv_inertia, exec_, "inv_inertia");
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
      h.wall_key.resize(this->keyed_history() ? kWallSlots * n : 0);
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
    reverse_start_.resize(n + 1);
    reverse_start_.upload(start, exec_, "reverse_start");
    exec_.synchronize();  // `start` is host memory about to go away
  }

  // Forgets all contacts (as the CPU engine's set_particles does).
  void clear_history() {
    for (auto& h : history_) {
      h.neighbour.fill_bytes(0, exec_);
      h.neighbour_mask.fill_bytes(0, exec_);
      h.wall.fill_bytes(0, exec_);
      h.wall_mask.fill_bytes(0, exec_);
      h.wall_key.fill_bytes(0, exec_);
    }
    neighbours_.fill_bytes(0xff, exec_);
    partner_id_.fill_bytes(0xff, exec_);
    partner_id_old_.fill_bytes(0xff, exec_);  // the first rebuild swaps them
    neighbour_count_.fill_bytes(0, exec_);
    neighbour_count_old_.fill_bytes(0, exec_);
    reverse_.fill_bytes(0xff, exec_);
    reverse_count_.fill_bytes(0, exec_);
    incoming_.fill_bytes(0, exec_);
  }

  // Sorts the particles by grid cell (stable sort of (cell, index): the same order as the CPU's
  // counting sort) and rebuilds the neighbour lists, carrying the history. The reordered state
  // goes to the back buffers, which then become current.
  void rebuild(const ContainerKinematics& container) {
    grid_ = this->rebuild_grid(container);
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
    if (this->keyed_history()) {
      g.wall_key_in = hin.wall_key.data();
      g.wall_key_out = hnew.wall_key.data();
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
    NeighbourBuildArgs b = this->build_args(t, cell_start_.data(), cell_end_.data());
    this->carry_history(b, order_.data(), slot_start_.data(), partner_id_old_.data(),
                        neighbour_count_old_.data(), hin, hnew);
    overflow_.fill_bytes(0, exec_);
    exec_.each(count_, BuildNeighbours{b, overflow_.data()}, "neighbour lists");
    exec_.each(count_, BuildReverse{b, overflow_.data()}, "reverse lists");

    travel_ = 0;
    current_ = next;
    needs_rebuild_ = false;
  }

  StepFn step_ = nullptr;
  int current_ = 0;
  std::string failure_;  // why compute() failed, until the state is set again
  Array<double> radius_next_, inv_mass_next_, inv_inertia_next_;  // rebuild scratch
  Array<std::int32_t> id_next_, partner_id_old_, neighbour_count_old_;
  Array<double> pair_load_;
  Array<std::uint32_t> cell_key_, cell_key_sorted_;
  Array<std::int32_t> order_in_, order_, cell_start_, cell_end_;
  Array<int> overflow_;
  Array<ParticleContribution> block_totals_;
};

}  // namespace gpu_engine
}  // namespace pdsim
