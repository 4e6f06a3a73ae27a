// The forward shading kernels (shade_kernels.hpp): the plain kernels (one model each), for the avx2 instruction set.
#include "shade_kernels.hpp"

#if SR_X86
namespace sr {
namespace shading {

SR_DEFINE_KERNEL(forward, Isa::Avx2, KernelKind::Headlight, ForwardTile, TileKernels::Forward)
SR_DEFINE_KERNEL(forward, Isa::Avx2, KernelKind::Unlit, ForwardTile, TileKernels::Forward)
SR_DEFINE_KERNEL(forward, Isa::Avx2, KernelKind::NormalColor, ForwardTile, TileKernels::Forward)

}  // namespace shading
}  // namespace sr
#endif
