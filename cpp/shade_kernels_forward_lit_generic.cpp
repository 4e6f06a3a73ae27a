// The forward shading kernels (shade_kernels.hpp): the lit kernel, for the generic instruction set.
#include "shade_kernels.hpp"

namespace sr {
namespace shading {

SR_DEFINE_KERNEL(forward, Isa::Generic, KernelKind::Lit, ForwardTile, TileKernels::Forward)

}  // namespace shading
}  // namespace sr
