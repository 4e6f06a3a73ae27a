// The deferred shading kernels (shade_kernels.hpp): the lit kernel, for the generic instruction set.
#include "shade_kernels.hpp"

namespace sr {
namespace shading {

SR_DEFINE_KERNEL(deferred, Isa::Generic, KernelKind::Lit, ShadeVisible, TileKernels::Deferred)

}  // namespace shading
}  // namespace sr
