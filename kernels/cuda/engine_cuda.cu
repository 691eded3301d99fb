// CUDA backend: the execution policy of the GPU engine (kernels/gpu_engine.hpp), whose
// orchestration the host reference launcher (kernels/gpu_engine_host.hpp) runs in CI. Here are
// only the kernels and their launches: each pass with one thread per particle on one stream,
// block sums in shared memory in the engine's fixed tree order. The only host synchronisation
// of a step is the copy of its totals (the coupling point); a neighbour-list rebuild adds none.
#include <cuda_runtime.h>

#include <cub/device/device_radix_sort.cuh>

#include <cstdlib>
#include <mutex>
#include <new>
#include <string>
#include <utility>

#include "kernels/gpu_engine.hpp"

namespace pdsim {
namespace gpu_engine {
namespace {

// The first fault of a kernel (an illegal address, a trap) that the CUDA runtime documents as
// fatal to the process's context: every later CUDA call fails with it, so that later engines
// and cuda_device_available() name it instead of failing for no reason of their own.
// Engines may run on several host threads (run --jobs).
std::mutex context_mutex;
std::string context_lost_by;
std::string context_lost() {
  const std::lock_guard<std::mutex> lock(context_mutex);
  return context_lost_by;
}

bool loses_context(cudaError_t status) {
  switch (status) {
    case cudaErrorIllegalAddress:
    case cudaErrorLaunchTimeout:
    case cudaErrorAssert:
    case cudaErrorHardwareStackError:
    case cudaErrorIllegalInstruction:
    case cudaErrorMisalignedAddress:
    case cudaErrorInvalidAddressSpace:
    case cudaErrorInvalidPc:
    case cudaErrorLaunchFailure:
      return true;
    default:
      return false;
  }
}

void check(cudaError_t status, const char* what) {
  if (status == cudaSuccess) return;
  std::string message = std::string("CUDA ") + what + " failed: " + cudaGetErrorString(status);
  if (loses_context(status)) {
    const std::lock_guard<std::mutex> lock(context_mutex);
    if (context_lost_by.empty()) context_lost_by = message;
    message +=
        " (this process's CUDA context is lost: no later CUDA work can run in it; "
        "PDSIM_CUDA_SYNC=1 names the kernel that failed)";
  }
  throw SimulationError(message);
}

// PDSIM_CUDA_SYNC=1: wait for and check every kernel as it is launched, so that a fault names
// its kernel (otherwise it shows at the step's copy of its totals). For debugging: it serialises
// the host with the device.
const bool kSyncEachKernel = [] {
  const char* value = std::getenv("PDSIM_CUDA_SYNC");
  return value != nullptr && std::string(value) == "1";
}();

// ---- kernels ----------------------------------------------------------------------------------

// ParticleContribution has default member initialisers, which __shared__ variables may not
// have: the reduction buffer is raw storage, and objects are created in it with placement new.
static_assert(alignof(ParticleContribution) <= alignof(double) &&
                  sizeof(ParticleContribution) % sizeof(double) == 0,
              "the shared reduction buffer is an array of doubles");
constexpr int kSharedDoubles = kBlock * sizeof(ParticleContribution) / sizeof(double);

// The block's kBlock contributions summed in the engine's fixed order; part[0] holds the result.
__device__ void reduce_block(ParticleContribution* part, int t) {
  __syncthreads();
  for (int stride = kBlock / 2; stride > 0; stride /= 2) {
    reduce_level(part, t, stride);
    __syncthreads();
  }
}

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

// One of the rebuild's passes (gpu_engine.hpp), one thread per particle.
template <class F>
__global__ void __launch_bounds__(kBlock) each_kernel(const __grid_constant__ F f, int count) {
  const int i = static_cast<int>(blockIdx.x * blockDim.x + threadIdx.x);
  if (i < count) f(i);
}

__global__ void probe_kernel() {}

// ---- the execution policy -----------------------------------------------------------------------

class CudaExec {
 public:
  // One device allocation (plain cudaMalloc). Resizing drops the contents.
  template <class T>
  class Array {
   public:
    Array() = default;
    ~Array() { cudaFree(data_); }
    Array(const Array&) = delete;
    Array& operator=(const Array&) = delete;

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
    void swap(Array& other) noexcept {
      std::swap(data_, other.data_);
      std::swap(size_, other.size_);
    }
    // Sets every byte (0 for zeros, 0xff for -1 in integers).
    void fill_bytes(int byte, const CudaExec& e) {
      if (size_ > 0) check(cudaMemsetAsync(data_, byte, bytes(), e.stream_), "cudaMemsetAsync");
    }
    void upload(const std::vector<T>& host, const CudaExec& e, const char* name) {
      if (host.size() != size_)
        throw SimulationError(std::string("DEM array '") + name + "' has " +
                              std::to_string(host.size()) + " values, the engine expects " +
                              std::to_string(size_));
      if (size_ > 0)
        check(cudaMemcpyAsync(data_, host.data(), bytes(), cudaMemcpyHostToDevice, e.stream_),
              "cudaMemcpyAsync (upload)");
    }
    std::vector<T> download(const CudaExec& e) const {
      std::vector<T> host(size_);
      if (size_ > 0)
        check(cudaMemcpyAsync(host.data(), data_, bytes(), cudaMemcpyDeviceToHost, e.stream_),
              "cudaMemcpyAsync (download)");
      e.synchronize();
      return host;
    }

   private:
    T* data_ = nullptr;
    std::size_t size_ = 0;
  };

  CudaExec() {
    if (const std::string lost = context_lost(); !lost.empty())
      throw SimulationError("an earlier CUDA error lost this process's context (" + lost +
                            "): no CUDA engine can start");
    int device = 0;
    check(cudaGetDevice(&device), "cudaGetDevice");
    cudaDeviceProp prop{};
    check(cudaGetDeviceProperties(&prop, device), "cudaGetDeviceProperties");
    device_name_ = prop.name;
    check(cudaStreamCreateWithFlags(&stream_, cudaStreamNonBlocking), "cudaStreamCreate");
    // Page-locked, so that the per-step copy of the totals is a true async DMA.
    check(cudaMallocHost(&totals_host_, sizeof(ParticleContribution)), "cudaMallocHost");
    new (totals_host_) ParticleContribution{};
    totals_device_.resize(1);
  }
  ~CudaExec() {
    cudaFreeHost(totals_host_);
    cudaStreamDestroy(stream_);
  }
  CudaExec(const CudaExec&) = delete;
  CudaExec& operator=(const CudaExec&) = delete;

  std::string name() const { return "cuda (" + device_name_ + ")"; }
  void synchronize() const { check(cudaStreamSynchronize(stream_), "cudaStreamSynchronize"); }

  // After a launch: its launch error, and with PDSIM_CUDA_SYNC=1 its execution error.
  void launched(const char* what) const {
    check(cudaGetLastError(), what);
    if (kSyncEachKernel) check(cudaStreamSynchronize(stream_), what);
  }

  template <class F>
  void each(int count, const F& f, const char* what) const {
    if (count <= 0) return;
    each_kernel<F><<<blocks_for(count), kBlock, 0, stream_>>>(f, count);
    launched(what);
  }

  void sort_pairs(const Array<std::uint32_t>& key_in, Array<std::uint32_t>& key_out,
                  const Array<std::int32_t>& value_in, Array<std::int32_t>& value_out, int count,
                  int end_bit) {
    std::size_t temp_bytes = 0;
    check(cub::DeviceRadixSort::SortPairs(nullptr, temp_bytes, key_in.data(), key_out.data(),
                                          value_in.data(), value_out.data(), count, 0, end_bit,
                                          stream_),
          "radix sort size query");
    if (temp_bytes > sort_temp_.size()) sort_temp_.resize(temp_bytes);
    check(cub::DeviceRadixSort::SortPairs(sort_temp_.data(), temp_bytes, key_in.data(),
                                          key_out.data(), value_in.data(), value_out.data(), count,
                                          0, end_bit, stream_),
          "radix sort");
    launched("radix sort");
  }

  template <class V>
  static void step(const ParticleStepArgs& args, ParticleContribution* block_totals, int blocks,
                   const CudaExec& e) {
    pair_kernel<PairLaws<V>><<<blocks, kBlock, 0, e.stream_>>>(args, block_totals);
    e.launched("pair kernel");
    particle_kernel<V><<<blocks, kBlock, 0, e.stream_>>>(args, block_totals);
    e.launched("particle kernel");
  }

  ParticleContribution sum_blocks(const ParticleContribution* block_totals, int blocks,
                                  const int* overflow) {
    sum_blocks_kernel<<<1, kBlock, 0, stream_>>>(block_totals, blocks, overflow,
                                                 totals_device_.data());
    launched("sum kernel");
    check(cudaMemcpyAsync(totals_host_, totals_device_.data(), sizeof(ParticleContribution),
                          cudaMemcpyDeviceToHost, stream_),
          "cudaMemcpyAsync (totals)");
    synchronize();
    return *totals_host_;
  }

 private:
  std::string device_name_;
  cudaStream_t stream_ = nullptr;
  ParticleContribution* totals_host_ = nullptr;
  Array<ParticleContribution> totals_device_;
  Array<unsigned char> sort_temp_;
};

}  // namespace
}  // namespace gpu_engine

std::unique_ptr<DemEngine> make_cuda_engine(const EngineConfig& config) {
  using Engine = gpu_engine::GpuEngine<gpu_engine::CudaExec>;
  return std::make_unique<Engine>(config, dispatch_variant(config, Engine::PickStep{}));
}

bool cuda_device_available(std::string* description) {
  auto fail = [&](const std::string& why) {
    cudaGetLastError();  // a failed query must not leave an error for later CUDA calls
    if (description) *description = why;
    return false;
  };
  if (const std::string lost = gpu_engine::context_lost(); !lost.empty())
    return fail("an earlier CUDA error lost this process's context: " + lost);
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
  const cudaError_t image = cudaFuncGetAttributes(&attributes, gpu_engine::probe_kernel);
  if (image != cudaSuccess) return fail(name + ": " + cudaGetErrorString(image));
  if (description) *description = name;
  return true;
}

}  // namespace pdsim
