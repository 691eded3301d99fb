// The host reference launcher: runs the GPU engine's orchestration (kernels/gpu_engine.hpp) on
// the CPU, one particle after another in the GPU's pass order, with the GPU's block sums. A pass
// writes only its own particle's entries, so the serial order gives the GPU's results bitwise;
// tests compare it with the CPU engine in every physics family, which CI cannot do on a GPU.
#pragma once

#include <algorithm>
#include <atomic>
#include <cstring>
#include <memory>
#include <numeric>
#include <string>
#include <vector>

#include "kernels/gpu_engine.hpp"

namespace pdsim::gpu_engine {

class HostExec {
 public:
  template <class T>
  class Array {
   public:
    // A new array holds a byte pattern that changes from one allocation to the next, as fresh
    // device memory holds whatever was there before: a result or a checkpoint that depends on
    // an unwritten value then differs between two equal runs here, as it would on a GPU.
    void resize(std::size_t n) {
      if (n == size_) return;
      data_.reset(n > 0 ? new T[n] : nullptr);
      size_ = n;
      static std::atomic<unsigned> allocations{0};
      fill_bytes(static_cast<int>(0x40 + allocations++ % 0x80), HostExec{});
    }
    T* data() const { return data_.get(); }
    std::size_t size() const { return size_; }
    std::size_t bytes() const { return size_ * sizeof(T); }
    void swap(Array& other) noexcept {
      std::swap(data_, other.data_);
      std::swap(size_, other.size_);
    }
    void fill_bytes(int byte, const HostExec&) {
      if (size_ > 0) std::memset(static_cast<void*>(data_.get()), byte, bytes());
    }
    void upload(const std::vector<T>& host, const HostExec&, const char* name) {
      if (host.size() != size_)
        throw SimulationError(std::string("DEM array '") + name + "' has " +
                              std::to_string(host.size()) + " values, the engine expects " +
                              std::to_string(size_));
      std::copy(host.begin(), host.end(), data_.get());
    }
    std::vector<T> download(const HostExec&) const {
      return std::vector<T>(data_.get(), data_.get() + size_);
    }

   private:
    std::unique_ptr<T[]> data_;
    std::size_t size_ = 0;
  };

  std::string name() const { return "host reference"; }
  void synchronize() const {}

  template <class F>
  void each(int count, const F& f, const char* /*what*/) const {
    for (int i = 0; i < count; ++i) f(i);
  }

  // Stable by key, as CUB's radix sort.
  void sort_pairs(const Array<std::uint32_t>& key_in, Array<std::uint32_t>& key_out,
                  const Array<std::int32_t>& value_in, Array<std::int32_t>& value_out, int count,
                  int end_bit) const {
    const std::uint32_t mask =
        end_bit >= 32 ? ~std::uint32_t{0} : (std::uint32_t{1} << end_bit) - 1;
    std::vector<int> order(static_cast<std::size_t>(count));
    std::iota(order.begin(), order.end(), 0);
    const std::uint32_t* key = key_in.data();
    std::stable_sort(order.begin(), order.end(),
                     [&](int a, int b) { return (key[a] & mask) < (key[b] & mask); });
    for (int i = 0; i < count; ++i) {
      key_out.data()[i] = key[order[static_cast<std::size_t>(i)]];
      value_out.data()[i] = value_in.data()[order[static_cast<std::size_t>(i)]];
    }
  }

  // The pair pass over every block, then the particle pass over every block, as the two
  // kernels; each block's kBlock contributions (zero past the last particle) summed as a GPU
  // block sums them.
  template <class V>
  static void step(const ParticleStepArgs& a, ParticleContribution* block_totals, int blocks,
                   const HostExec&) {
    std::vector<ParticleContribution> part(kBlock);
    auto block_sum = [&](int b, auto&& pass) {
      for (int t = 0; t < kBlock; ++t) {
        part[static_cast<std::size_t>(t)] = ParticleContribution{};
        const int i = b * kBlock + t;
        if (i < a.count) pass(i, part[static_cast<std::size_t>(t)]);
      }
      reduce(part.data());
      return part[0];
    };
    for (int b = 0; b < blocks; ++b)
      block_totals[b] =
          block_sum(b, [&](int i, ParticleContribution& c) { pair_pass<PairLaws<V>>(i, a, c); });
    for (int b = 0; b < blocks; ++b)
      accumulate(block_totals[b],
                 block_sum(b, [&](int i, ParticleContribution& c) { particle_pass<V>(i, a, c); }));
  }

  // As the CUDA sum kernel: "thread" t sums blocks t, t + kBlock, ... in order, then the tree.
  ParticleContribution sum_blocks(const ParticleContribution* block_totals, int blocks,
                                  const int* overflow) const {
    std::vector<ParticleContribution> part(kBlock);
    for (int t = 0; t < kBlock; ++t)
      for (int b = t; b < blocks; b += kBlock)
        accumulate(part[static_cast<std::size_t>(t)], block_totals[b]);
    reduce(part.data());
    ParticleContribution total = part[0];
    if (*overflow) total.flags |= kNeighbourOverflow;
    flag_non_finite(total);
    return total;
  }

 private:
  static void reduce(ParticleContribution* part) {
    for (int stride = kBlock / 2; stride > 0; stride /= 2)
      for (int t = 0; t < stride; ++t) reduce_level(part, t, stride);
  }
};

using HostReferenceEngine = GpuEngine<HostExec>;

}  // namespace pdsim::gpu_engine
