// The forward shading kernels (shade_kernels.hpp): the plain kernels (one model each), for the generic instruction set.
#include "shade_kernels.hpp"

namespace sr {
namespace shading {

SR_DEFINE_KERNEL(forward, Isa::Generic, KernelKind::Headlight, ForwardTile, TileKernels::Forward)
SR_DEFINE_KERNEL(forward, Isa::Generic, KernelKind::Unlit, ForwardTile, TileKernels::Forward)
SR_DEFINE_KERNEL(forward, Isa::Generic, KernelKind::NormalColor, ForwardTile, TileKernels::Forward)

}  // namespace shading
}  // namespace sr
