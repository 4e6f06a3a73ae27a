// The deferred shading kernels (shade_kernels.hpp): the plain kernels (one model each), for the generic instruction set.
#include "shade_kernels.hpp"

namespace sr {
namespace shading {

SR_DEFINE_KERNEL(deferred, Isa::Generic, KernelKind::Headlight, ShadeVisible, TileKernels::Deferred)
SR_DEFINE_KERNEL(deferred, Isa::Generic, KernelKind::Unlit, ShadeVisible, TileKernels::Deferred)
SR_DEFINE_KERNEL(deferred, Isa::Generic, KernelKind::NormalColor, ShadeVisible, TileKernels::Deferred)

}  // namespace shading
}  // namespace sr
