// CUDA backend: launches the shared per-particle functions (kernels/particle_step.hpp,
// kernels/neighbours.hpp) with one thread per particle on one stream. Totals are reduced per
// block of kBlock particles in a fixed tree order, then over the blocks in a fixed order, so two
// runs are bitwise identical. The only host synchronisation of a step is the copy of its totals
// (the coupling point); a neighbour-list rebuild adds none.
#include <cuda_runtime.h>

#include <cub/device/device_radix_sort.cuh>

#include <algorithm>
#include <cmath>
#include <new>
#include <numeric>
#include <utility>

#include "kernels/neighbours.hpp"
#include "kernels/variant_dispatch.hpp"

namespace pdsim {
namespace {

constexpr int kBlock = 256;  // threads per block = particles per reduction block

void check(cudaError_t status, const char* what) {
  if (status != cudaSuccess)
    throw SimulationError(std::string("CUDA ") + what + " failed: " + cudaGetErrorString(status));
}

int blocks_for(int count) {
  return (count + kBlock - 1) / kBlock;
}

class Stream {
 public:
  Stream() {
    check(cudaStreamCreateWithFlags(&stream_, cudaStreamNonBlocking), "cudaStreamCreate");
  }
  ~Stream() { cudaStreamDestroy(stream_); }
  Stream(const Stream&) = delete;
  Stream& operator=(const Stream&) = delete;
  cudaStream_t get() const { return stream_; }
  void synchronize() const { check(cudaStreamSynchronize(stream_), "cudaStreamSynchronize"); }

 private:
  cudaStream_t stream_ = nullptr;
};

// Owns one device allocation (plain cudaMalloc). Resizing drops the contents.
template <class T>
class DeviceArray {
 public:
  DeviceArray() = default;
  ~DeviceArray() { cudaFree(data_); }
  DeviceArray(const DeviceArray&) = delete;
  DeviceArray& operator=(const DeviceArray&) = delete;

  void resize(std::size_t n) {
    if (n == size_) return;
    cudaFree(data_);
    data_ = nullptr;
    size_ = 0;
    if (n > 0) check(cudaMalloc(&data_, n * sizeof(T)), "cudaMalloc");
    size_ = n;
  }
  T* data() const { return data_; }
  std::size_t size() const { return size_; }
  std::size_t bytes() const { return size_ * sizeof(T); }
  void swap(DeviceArray& other) noexcept {
    std::swap(data_, other.data_);
    std::swap(size_, other.size_);
  }
  // Sets every byte (0 for zeros, 0xff for -1 in integers).
  void fill_bytes(int byte, cudaStream_t stream) {
    if (size_ > 0) check(cudaMemsetAsync(data_, byte, bytes(), stream), "cudaMemsetAsync");
  }
  void upload(const std::vector<T>& host, cudaStream_t stream, const char* name) {
    if (host.size() != size_)
      throw SimulationError(std::string("DEM array '") + name + "' has " +
                            std::to_string(host.size()) + " values, the engine expects " +
                            std::to_string(size_));
    if (size_ > 0)
      check(cudaMemcpyAsync(data_, host.data(), bytes(), cudaMemcpyHostToDevice, stream),
            "cudaMemcpyAsync (upload)");
  }
  std::vector<T> download(const Stream& stream) const {
    std::vector<T> host(size_);
    if (size_ > 0)
      check(cudaMemcpyAsync(host.data(), data_, bytes(), cudaMemcpyDeviceToHost, stream.get()),
            "cudaMemcpyAsync (download)");
    stream.synchronize();
    return host;
  }
  void copy_from(const DeviceArray& source, cudaStream_t stream) {
    if (size_ > 0)
      check(cudaMemcpyAsync(data_, source.data_, bytes(), cudaMemcpyDeviceToDevice, stream),
            "cudaMemcpyAsync (device)");
  }

 private:
  T* data_ = nullptr;
  std::size_t size_ = 0;
};

// Page-locked host memory, so that the per-step copy of the totals is a true async DMA.
template <class T>
class PinnedHost {
 public:
  PinnedHost() {
    check(cudaMallocHost(&data_, sizeof(T)), "cudaMallocHost");
    new (data_) T{};
  }
  ~PinnedHost() { cudaFreeHost(data_); }
  PinnedHost(const PinnedHost&) = delete;
  PinnedHost& operator=(const PinnedHost&) = delete;
  T* get() const { return data_; }

 private:
  T* data_ = nullptr;
};

// ---- kernels ----------------------------------------------------------------------------------

// Tree reduction of kBlock contributions in shared memory; the pairing is fixed, so the sum is
// reproducible. part[0] holds the result.
__device__ void reduce_block(ParticleContribution* part, int t) {
  __syncthreads();
  for (int stride = kBlock / 2; stride > 0; stride /= 2) {
    if (t < stride) accumulate(part[t], part[t + stride]);
    __syncthreads();
  }
}

// ParticleContribution has default member initialisers, which __shared__ variables may not
// have: the reduction buffer is raw storage, and objects are created in it with placement new.
static_assert(alignof(ParticleContribution) <= alignof(double) &&
                  sizeof(ParticleContribution) % sizeof(double) == 0,
              "the shared reduction buffer is an array of doubles");
constexpr int kSharedDoubles = kBlock * sizeof(ParticleContribution) / sizeof(double);

// Pair pass: each block's dissipation goes to its block total.
template <class V>
__global__ void __launch_bounds__(kBlock)
    pair_kernel(const __grid_constant__ ParticleStepArgs args, ParticleContribution* block_totals) {
  __shared__ double storage[kSharedDoubles];
  auto* part = reinterpret_cast<ParticleContribution*>(storage);
  const int t = static_cast<int>(threadIdx.x);
  const int i = static_cast<int>(blockIdx.x) * kBlock + t;
  ParticleContribution c;
  if (i < args.count) pair_pass<V>(i, args, c);
  new (part + t) ParticleContribution(c);
  reduce_block(part, t);
  if (t == 0) block_totals[blockIdx.x] = part[0];
}

// Particle pass: adds each block's sums to the block total of the pair pass.
template <class V>
__global__ void __launch_bounds__(kBlock)
    particle_kernel(const __grid_constant__ ParticleStepArgs args,
                    ParticleContribution* block_totals) {
  __shared__ double storage[kSharedDoubles];
  auto* part = reinterpret_cast<ParticleContribution*>(storage);
  const int t = static_cast<int>(threadIdx.x);
  const int i = static_cast<int>(blockIdx.x) * kBlock + t;
  ParticleContribution c;
  if (i < args.count) particle_pass<V>(i, args, c);
  new (part + t) ParticleContribution(c);
  reduce_block(part, t);
  if (t == 0) accumulate(block_totals[blockIdx.x], part[0]);
}

// One block: sums the block totals in a fixed order and adds the rebuild's overflow flag.
__global__ void __launch_bounds__(kBlock)
    sum_blocks_kernel(const ParticleContribution* block_totals, int blocks,
                      const int* neighbour_overflow, ParticleContribution* totals) {
  __shared__ double storage[kSharedDoubles];
  auto* part = reinterpret_cast<ParticleContribution*>(storage);
  const int t = static_cast<int>(threadIdx.x);
  ParticleContribution sum;
  for (int b = t; b < blocks; b += kBlock) accumulate(sum, block_totals[b]);
  new (part + t) ParticleContribution(sum);
  reduce_block(part, t);
  if (t == 0) {
    ParticleContribution total = part[0];
    if (*neighbour_overflow) total.flags |= kNeighbourOverflow;
    flag_non_finite(total);
    *totals = total;
  }
}

__global__ void cell_kernel(int count, Grid grid, const double* x, const double* y, const double* z,
                            std::uint32_t* cell, std::int32_t* index) {
  const int i = static_cast<int>(blockIdx.x * blockDim.x + threadIdx.x);
  if (i >= count) return;
  cell[i] = static_cast<std::uint32_t>(cell_of(grid, {x[i], y[i], z[i]}));
  index[i] = i;
}

// Per-particle arrays that move with the particles when they are reordered by cell.
constexpr int kGatheredColumns = 12;  // x y z vx vy vz wx wy wz radius inv_mass inv_inertia
struct GatherArgs {
  int count;
  const std::int32_t* order;  // new index -> old index
  const double* column_in[kGatheredColumns];
  double* column_out[kGatheredColumns];
  const std::int32_t* id_in;
  std::int32_t* id_out;
  const double* wall_history_in;  // nullptr when the scene has no tangential history
  double* wall_history_out;
  const std::uint8_t* wall_mask_in;
  std::uint8_t* wall_mask_out;
};

__global__ void gather_kernel(const __grid_constant__ GatherArgs a) {
  const int i = static_cast<int>(blockIdx.x * blockDim.x + threadIdx.x);
  if (i >= a.count) return;
  const int from = a.order[i];
#pragma unroll
  for (int c = 0; c < kGatheredColumns; ++c) a.column_out[c][i] = a.column_in[c][from];
  a.id_out[i] = a.id_in[from];
  if (a.wall_history_in) {
    for (int s = 0; s < 3 * kWallSlots; ++s)
      a.wall_history_out[3 * kWallSlots * i + s] = a.wall_history_in[3 * kWallSlots * from + s];
    a.wall_mask_out[i] = a.wall_mask_in[from];
  }
}

// Cells start and end where the sorted cell index changes; empty cells keep start = end = 0.
__global__ void cell_range_kernel(int count, const std::uint32_t* sorted_cell,
                                  std::int32_t* cell_start, std::int32_t* cell_end) {
  const int i = static_cast<int>(blockIdx.x * blockDim.x + threadIdx.x);
  if (i >= count) return;
  const std::uint32_t c = sorted_cell[i];
  if (i == 0 || sorted_cell[i - 1] != c) cell_start[c] = i;
  if (i == count - 1 || sorted_cell[i + 1] != c) cell_end[c] = i + 1;
}

__global__ void neighbour_kernel(const __grid_constant__ NeighbourBuildArgs args, int* overflow) {
  const int i = static_cast<int>(blockIdx.x * blockDim.x + threadIdx.x);
  if (i >= args.count) return;
  if (!build_neighbours_of(i, args)) *overflow = 1;
}

// After neighbour_kernel (it reads every forward list).
__global__ void reverse_kernel(const __grid_constant__ NeighbourBuildArgs args, int* overflow) {
  const int i = static_cast<int>(blockIdx.x * blockDim.x + threadIdx.x);
  if (i >= args.count) return;
  if (!build_reverse_of(i, args)) *overflow = 1;
}

__global__ void probe_kernel() {}

// What the engine needs from the kernel variant: the only code instantiated per variant is the
// two step kernels and their launcher; everything else is shared.
using StepLauncher = void (*)(const ParticleStepArgs&, ParticleContribution* block_totals,
                              int blocks, cudaStream_t);

template <class V>
void launch_step(const ParticleStepArgs& args, ParticleContribution* block_totals, int blocks,
                 cudaStream_t stream) {
  pair_kernel<V><<<blocks, kBlock, 0, stream>>>(args, block_totals);
  particle_kernel<V><<<blocks, kBlock, 0, stream>>>(args, block_totals);
}

struct StepVariant {
  StepLauncher launch;
  std::string name;
  bool history, polydisperse;
  int pair_doubles;
};

struct PickStep {
  template <class V>
  StepVariant operator()() const {
    return {&launch_step<V>, variant_string<V>(), V::Tangential::kHistory, V::kPolydisperse,
            pair_doubles<V>()};
  }
};

// ---- engine -----------------------------------------------------------------------------------

struct DeviceState {
  DeviceArray<double> x, y, z, vx, vy, vz, wx, wy, wz;
  DeviceArray<double>* all[9] = {&x, &y, &z, &vx, &vy, &vz, &wx, &wy, &wz};
  ParticleArrays view() const {
    return {x.data(),  y.data(),  z.data(),  vx.data(), vy.data(),
            vz.data(), wx.data(), wy.data(), wz.data()};
  }
};

struct DeviceHistory {
  DeviceArray<double> neighbour, wall;
  DeviceArray<std::uint64_t> neighbour_mask;
  DeviceArray<std::uint8_t> wall_mask;
};

const char* const kStateNames[9] = {"x", "y", "z", "vx", "vy", "vz", "wx", "wy", "wz"};

class CudaEngine final : public DemEngine {
 public:
  CudaEngine(const EngineConfig& c, StepVariant step) : config_(c), step_(std::move(step)) {
    count_ = static_cast<int>(c.particles.size());
    if (count_ == 0 || c.radius.size() != c.particles.size())
      throw SimulationError("the CUDA DEM engine needs one radius per particle and >= 1 particle");
    const auto [rmin_it, rmax_it] = std::minmax_element(c.radius.begin(), c.radius.end());
    r_min_ = *rmin_it;
    r_max_ = *rmax_it;
    skin_ = default_skin(r_min_, c.skin);
    max_neighbours_ = neighbour_slots(r_min_, r_max_, skin_);
    check_particle_count(count_, max_neighbours_);
    check_fits(c.geometry, r_max_);
    int device = 0;
    check(cudaGetDevice(&device), "cudaGetDevice");
    cudaDeviceProp prop{};
    check(cudaGetDeviceProperties(&prop, device), "cudaGetDeviceProperties");
    device_name_ = prop.name;

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
    totals_device_.resize(1);
    overflow_.resize(1);
    overflow_.fill_bytes(0, stream_.get());

    radius_host_ = c.radius;
    upload_particle_constants();
    std::vector<std::int32_t> id(n);
    std::iota(id.begin(), id.end(), 0);
    id_.upload(id, stream_.get(), "id");
    size_neighbour_arrays();
    set_particles(c.particles);
  }

  const StepTotals& compute(const ContainerKinematics& container, double dt) override {
    if (needs_rebuild_) rebuild(container);
    dt_ = dt;
    const ParticleStepArgs a = args(container, dt);
    const int blocks = blocks_for(count_);
    step_.launch(a, block_totals_.data(), blocks, stream_.get());
    check(cudaGetLastError(), "step kernel launch");
    sum_blocks_kernel<<<1, kBlock, 0, stream_.get()>>>(block_totals_.data(), blocks,
                                                       overflow_.data(), totals_device_.data());
    check(cudaGetLastError(), "sum kernel launch");
    check(cudaMemcpyAsync(totals_host_.get(), totals_device_.data(), sizeof(StepTotals),
                          cudaMemcpyDeviceToHost, stream_.get()),
          "cudaMemcpyAsync (totals)");
    stream_.synchronize();
    totals_ = *totals_host_.get();
    if (totals_.flags & kNeighbourOverflow)
      throw SimulationError("neighbour list overflow (" + std::to_string(max_neighbours_) +
                            " slots): particles are packed beyond the densest packing; the "
                            "simulation has most likely blown up");
    return totals_;
  }

  void accept() override {
    current_ ^= 1;
    if (lists_expired(travel_, totals_.speed_sq, dt_, skin_)) needs_rebuild_ = true;
  }

  int count() const override { return count_; }
  std::string variant() const override { return step_.name; }
  std::string backend() const override { return "cuda (" + device_name_ + ")"; }
  int threads() const override {
    return 1;  // host threads; the device work is one thread per particle
  }

  std::vector<ParticleState> particles() const override {
    const DeviceState& s = state_[current_];
    std::vector<std::vector<double>> c;
    for (const auto* a : s.all) c.push_back(a->download(stream_));
    const std::vector<std::int32_t> id = id_.download(stream_);
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
    const std::vector<std::int32_t> id = id_.download(stream_);
    std::vector<std::vector<double>> c(9, std::vector<double>(p.size()));
    for (std::size_t i = 0; i < p.size(); ++i) {
      const ParticleState& q = p[static_cast<std::size_t>(id[i])];
      const double values[9] = {q.position.x, q.position.y, q.position.z,
                                q.velocity.x, q.velocity.y, q.velocity.z,
                                q.spin.x,     q.spin.y,     q.spin.z};
      for (int k = 0; k < 9; ++k) c[static_cast<std::size_t>(k)][i] = values[k];
    }
    DeviceState& s = state_[current_];
    for (int k = 0; k < 9; ++k)
      s.all[k]->upload(c[static_cast<std::size_t>(k)], stream_.get(), kStateNames[k]);
    clear_history();
    stream_.synchronize();  // the uploads read pageable host memory that is about to go away
    needs_rebuild_ = true;
  }

  StateArrays save() const override {
    StateArrays out;
    const DeviceState& s = state_[current_];
    for (int k = 0; k < 9; ++k) out[kStateNames[k]] = s.all[k]->download(stream_);
    out["id"] = id_.download(stream_);
    out["radius"] = radius_.download(stream_);
    const DeviceHistory& h = history_[current_];
    std::vector<std::uint64_t> neighbour_mask = h.neighbour_mask.download(stream_);
    std::vector<std::uint8_t> wall_mask = h.wall_mask.download(stream_);
    out["history"] = live_history(h.neighbour.download(stream_), neighbour_mask, max_neighbours_);
    out["wall_history"] = live_history(h.wall.download(stream_), wall_mask, kWallSlots);
    out["wall_mask"] = std::move(wall_mask);
    out["neighbour_mask"] = std::move(neighbour_mask);
    out["neighbours"] = neighbours_.download(stream_);
    out["partner_id"] = partner_id_.download(stream_);
    out["neighbour_count"] = neighbour_count_.download(stream_);
    out["reverse"] = flat_reverse(reverse_.download(stream_), max_neighbours_);
    out["reverse_count"] = reverse_count_.download(stream_);
    put_grid(out, {grid_, needs_rebuild_, max_neighbours_, travel_});
    return out;
  }

  void restore(const StateArrays& in) override {
    const GridState g = get_grid(in);
    max_neighbours_ = g.max_neighbours;
    size_neighbour_arrays();
    const cudaStream_t stream = stream_.get();
    DeviceState& s = state_[current_];
    for (int k = 0; k < 9; ++k)
      s.all[k]->upload(state_values<double>(in, kStateNames[k]), stream, kStateNames[k]);
    id_.upload(state_values<std::int32_t>(in, "id"), stream, "id");
    radius_host_ = state_values<double>(in, "radius");
    if (radius_host_.size() != static_cast<std::size_t>(count_))
      throw SimulationError("checkpoint DEM array 'radius' does not match the particle count");
    upload_particle_constants();
    clear_history();
    DeviceHistory& h = history_[current_];
    h.neighbour.upload(state_values<double>(in, "history"), stream, "history");
    h.wall.upload(state_values<double>(in, "wall_history"), stream, "wall_history");
    h.wall_mask.upload(state_values<std::uint8_t>(in, "wall_mask"), stream, "wall_mask");
    h.neighbour_mask.upload(state_values<std::uint64_t>(in, "neighbour_mask"), stream,
                            "neighbour_mask");
    neighbours_.upload(state_values<std::int32_t>(in, "neighbours"), stream, "neighbours");
    partner_id_.upload(state_values<std::int32_t>(in, "partner_id"), stream, "partner_id");
    neighbour_count_.upload(state_values<std::int32_t>(in, "neighbour_count"), stream,
                            "neighbour_count");
    reverse_.upload(packed_reverse(state_values<std::int32_t>(in, "reverse"), max_neighbours_),
                    stream, "reverse");
    reverse_count_.upload(state_values<std::int32_t>(in, "reverse_count"), stream, "reverse_count");
    needs_rebuild_ = g.needs_rebuild;
    overflow_.fill_bytes(0, stream);
    travel_ = g.travel;
    grid_ = g.grid;
    stream_.synchronize();
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
  // Mass and inertia of solid spheres, computed as in the CPU engine's constructor.
  void upload_particle_constants() {
    const std::size_t n = radius_host_.size();
    std::vector<double> inv_mass(n), inv_inertia(n);
    for (std::size_t i = 0; i < n; ++i) {
      const SphereMass m = sphere_mass(radius_host_[i], config_.density);
      inv_mass[i] = m.inv_mass;
      inv_inertia[i] = m.inv_inertia;
    }
    radius_.upload(radius_host_, stream_.get(), "radius");
    inv_mass_.upload(inv_mass, stream_.get(), "inv_mass");
    inv_inertia_.upload(inv_inertia, stream_.get(), "inv_inertia");
    stream_.synchronize();
  }

  void size_neighbour_arrays() {
    const std::size_t n = static_cast<std::size_t>(count_);
    const std::size_t slots = n * static_cast<std::size_t>(max_neighbours_);
    for (auto& h : history_) {
      h.neighbour.resize(step_.history ? 3 * slots : 0);
      h.neighbour_mask.resize(n);
      h.wall.resize(step_.history ? 3 * kWallSlots * n : 0);
      h.wall_mask.resize(n);
    }
    for (auto* a : {&neighbours_, &partner_id_, &partner_id_old_, &reverse_}) a->resize(slots);
    neighbour_count_.resize(n);
    neighbour_count_old_.resize(n);
    reverse_count_.resize(n);
    incoming_.resize(n);
    pair_load_.resize(static_cast<std::size_t>(step_.pair_doubles) * slots);
    // Fixed stride: particle i's lists start at i * max_neighbours (forward and reverse alike).
    std::vector<std::int32_t> start(n + 1);
    for (std::size_t i = 0; i <= n; ++i) start[i] = static_cast<std::int32_t>(i) * max_neighbours_;
    slot_start_.upload(start, stream_.get(), "slot_start");
    stream_.synchronize();  // `start` is pageable host memory about to go away
  }

  // Forgets all contacts (as the CPU engine's set_particles does).
  void clear_history() {
    const cudaStream_t stream = stream_.get();
    for (auto& h : history_) {
      h.neighbour.fill_bytes(0, stream);
      h.neighbour_mask.fill_bytes(0, stream);
      h.wall.fill_bytes(0, stream);
      h.wall_mask.fill_bytes(0, stream);
    }
    neighbours_.fill_bytes(0xff, stream);
    partner_id_.fill_bytes(0xff, stream);
    neighbour_count_.fill_bytes(0, stream);
    reverse_.fill_bytes(0xff, stream);
    reverse_count_.fill_bytes(0, stream);
    incoming_.fill_bytes(0, stream);
  }

  ParticleStepArgs args(const ContainerKinematics& container, double dt) const {
    const DeviceHistory& hin = history_[current_];
    const DeviceHistory& hout = history_[current_ ^ 1];
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

  // Sorts the particles by grid cell (stable radix sort of (cell, index): the same order as the
  // CPU's counting sort) and rebuilds the neighbour lists, carrying the history. The reordered
  // state goes to the back buffers, which then become current.
  void rebuild(const ContainerKinematics& container) {
    const cudaStream_t stream = stream_.get();
    const int blocks = blocks_for(count_);
    grid_ = grid_around(container.position, config_.geometry.half_size, 2 * r_max_ + skin_);
    const int cells = grid_.nx * grid_.ny * grid_.nz;
    cell_start_.resize(static_cast<std::size_t>(cells));
    cell_end_.resize(static_cast<std::size_t>(cells));

    const DeviceState& s = state_[current_];
    cell_kernel<<<blocks, kBlock, 0, stream>>>(count_, grid_, s.x.data(), s.y.data(), s.z.data(),
                                               cell_key_.data(), order_in_.data());
    check(cudaGetLastError(), "cell kernel launch");
    int end_bit = 1;
    while (end_bit < 32 && (std::uint32_t{1} << end_bit) < static_cast<std::uint32_t>(cells))
      ++end_bit;
    std::size_t temp_bytes = 0;
    check(cub::DeviceRadixSort::SortPairs(nullptr, temp_bytes, cell_key_.data(),
                                          cell_key_sorted_.data(), order_in_.data(), order_.data(),
                                          count_, 0, end_bit, stream),
          "radix sort size query");
    if (temp_bytes > sort_temp_.size()) sort_temp_.resize(temp_bytes);
    check(cub::DeviceRadixSort::SortPairs(sort_temp_.data(), temp_bytes, cell_key_.data(),
                                          cell_key_sorted_.data(), order_in_.data(), order_.data(),
                                          count_, 0, end_bit, stream),
          "radix sort");

    const int next = current_ ^ 1;
    const DeviceState& t = state_[next];
    GatherArgs g{};
    g.count = count_;
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
    DeviceHistory& hin = history_[current_];
    DeviceHistory& hnew = history_[next];
    if (step_.history) {
      g.wall_history_in = hin.wall.data();
      g.wall_history_out = hnew.wall.data();
      g.wall_mask_in = hin.wall_mask.data();
      g.wall_mask_out = hnew.wall_mask.data();
    }
    gather_kernel<<<blocks, kBlock, 0, stream>>>(g);
    check(cudaGetLastError(), "gather kernel launch");
    radius_.swap(radius_next_);
    inv_mass_.swap(inv_mass_next_);
    inv_inertia_.swap(inv_inertia_next_);
    id_.swap(id_next_);

    cell_start_.fill_bytes(0, stream);
    cell_end_.fill_bytes(0, stream);
    cell_range_kernel<<<blocks, kBlock, 0, stream>>>(count_, cell_key_sorted_.data(),
                                                     cell_start_.data(), cell_end_.data());
    check(cudaGetLastError(), "cell range kernel launch");

    partner_id_.swap(partner_id_old_);
    neighbour_count_.swap(neighbour_count_old_);
    NeighbourBuildArgs b{};
    b.count = count_;
    b.grid = grid_;
    b.x = t.x.data();
    b.y = t.y.data();
    b.z = t.z.data();
    b.radius = step_.polydisperse ? radius_.data() : nullptr;
    b.mono_radius = scene_args_.mono_radius;
    b.skin = skin_;
    b.cell_start = cell_start_.data();
    b.cell_end = cell_end_.data();
    b.id = id_.data();
    if (step_.history) {
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
    overflow_.fill_bytes(0, stream);
    neighbour_kernel<<<blocks, kBlock, 0, stream>>>(b, overflow_.data());
    check(cudaGetLastError(), "neighbour kernel launch");
    reverse_kernel<<<blocks, kBlock, 0, stream>>>(b, overflow_.data());
    check(cudaGetLastError(), "reverse kernel launch");

    travel_ = 0;
    current_ = next;
    needs_rebuild_ = false;
  }

  EngineConfig config_;
  ParticleStepArgs scene_args_ = scene_step_args(config_);
  StepVariant step_;
  Stream stream_;  // declared before the arrays, so destroyed after them
  int count_ = 0, max_neighbours_ = 1, current_ = 0;
  double r_min_ = 0, r_max_ = 0, skin_ = 0;
  double dt_ = 0, travel_ = 0;  // last step size; drift bound since the last build (m)
  std::string device_name_;
  std::vector<double> radius_host_;
  DeviceState state_[2];
  DeviceHistory history_[2];
  DeviceArray<double> radius_, inv_mass_, inv_inertia_;
  DeviceArray<double> radius_next_, inv_mass_next_, inv_inertia_next_;  // rebuild scratch
  DeviceArray<std::int32_t> id_, id_next_, neighbours_, partner_id_, partner_id_old_;
  DeviceArray<std::int32_t> neighbour_count_, neighbour_count_old_, reverse_, reverse_count_;
  DeviceArray<std::int32_t> slot_start_;
  DeviceArray<std::uint32_t> incoming_;
  DeviceArray<double> pair_load_;
  DeviceArray<std::uint32_t> cell_key_, cell_key_sorted_;
  DeviceArray<std::int32_t> order_in_, order_, cell_start_, cell_end_;
  DeviceArray<unsigned char> sort_temp_;
  DeviceArray<int> overflow_;
  DeviceArray<ParticleContribution> block_totals_, totals_device_;
  PinnedHost<ParticleContribution> totals_host_;
  Grid grid_{};
  bool needs_rebuild_ = true;
  StepTotals totals_;
};

}  // namespace

std::unique_ptr<DemEngine> make_cuda_engine(const EngineConfig& config) {
  return std::make_unique<CudaEngine>(config, dispatch_variant(config, PickStep{}));
}

bool cuda_device_available(std::string* description) {
  auto fail = [&](const std::string& why) {
    cudaGetLastError();  // a failed query must not leave an error for later CUDA calls
    if (description) *description = why;
    return false;
  };
  int devices = 0;
  const cudaError_t status = cudaGetDeviceCount(&devices);
  if (status == cudaErrorInsufficientDriver)
    return fail("no CUDA driver, or one older than this CUDA runtime");
  if (status == cudaErrorNoDevice || (status == cudaSuccess && devices == 0))
    return fail("no CUDA device");
  if (status != cudaSuccess) return fail(cudaGetErrorString(status));
  int device = 0;
  cudaDeviceProp prop{};
  if (cudaGetDevice(&device) != cudaSuccess ||
      cudaGetDeviceProperties(&prop, device) != cudaSuccess)
    return fail("cannot query the CUDA device");
  const std::string name = std::string(prop.name) + " (compute capability " +
                           std::to_string(prop.major) + "." + std::to_string(prop.minor) + ")";
  // The library holds sm_90 code and compute_90 PTX: older devices cannot run it.
  cudaFuncAttributes attributes{};
  const cudaError_t image = cudaFuncGetAttributes(&attributes, probe_kernel);
  if (image != cudaSuccess) return fail(name + ": " + cudaGetErrorString(image));
  if (description) *description = name;
  return true;
}

}  // namespace pdsim
