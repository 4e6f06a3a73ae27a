// Run-time choice of instruction set for the kernels written against simd.hpp.
#include "simd.hpp"

namespace sr {

Isa best_isa() {
#if SR_X86
  return __builtin_cpu_supports("avx2") ? Isa::Avx2 : Isa::Generic;
#else
  return Isa::Generic;  // (no AVX2 kernels are compiled for other machines)
#endif
}

const char* isa_name(Isa isa) { return isa == Isa::Avx2 ? "avx2" : "generic"; }

}  // namespace sr
