// Engine factories: the backend, then the variant's share of the CPU engines. The engines
// themselves (engine_cpu.hpp) are instantiated in translation units that CMake generates from
// engine_cpu_variants.cpp.in, one per normal law, tangential law and rolling choice, so that
// the build compiles them in parallel and a change recompiles them side by side.
#include "kernels/engine.hpp"
#include "kernels/variant_dispatch.hpp"

namespace pdsim {

template <class N, class T, bool R>
std::unique_ptr<DemEngine> make_cpu_engine_of(const EngineConfig& config);  // engine_cpu.hpp

namespace {

using CpuFactory = std::unique_ptr<DemEngine> (*)(const EngineConfig&);

struct PickFactory {
  template <class N, class T, bool R>
  CpuFactory operator()() const {
    return &make_cpu_engine_of<N, T, R>;
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
  return dispatch_laws(config, PickFactory{})(config);
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
