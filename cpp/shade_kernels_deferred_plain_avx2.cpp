// The deferred shading kernels (shade_kernels.hpp): the plain kernels (one model each), for the avx2 instruction set.
#include "shade_kernels.hpp"

#if SR_X86
namespace sr {
namespace shading {

SR_DEFINE_KERNEL(deferred, Isa::Avx2, KernelKind::Headlight, ShadeVisible, TileKernels::Deferred)
SR_DEFINE_KERNEL(deferred, Isa::Avx2, KernelKind::Unlit, ShadeVisible, TileKernels::Deferred)
SR_DEFINE_KERNEL(deferred, Isa::Avx2, KernelKind::NormalColor, ShadeVisible, TileKernels::Deferred)

}  // namespace shading
}  // namespace sr
#endif
