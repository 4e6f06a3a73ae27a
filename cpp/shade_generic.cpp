// The shading kernels compiled for the generic instruction set (shade_kernels.hpp).
#include "shade_kernels.hpp"

namespace sr {
namespace shading {

template <>
TileKernels::Deferred select_deferred<Isa::Generic>(const SamplePattern& pattern, Shading shading,
                                                  bool color, bool normal) {
  return make_select_deferred<Isa::Generic>(pattern, shading, color, normal);
}

template <>
TileKernels::Forward select_forward<Isa::Generic>(const SamplePattern& pattern, Shading shading,
                                                bool color, bool normal) {
  return make_select_forward<Isa::Generic>(pattern, shading, color, normal);
}

}  // namespace shading
}  // namespace sr
