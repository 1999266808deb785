// exact_fp.h: refuses a C++ translation unit that would compile the shared core's arithmetic without the
// exact floating-point flags. The core rounds as the shader does only without contraction into fused
// multiply-adds and without fast-math (DESIGN.md §6); a consumer that includes compute/shared/lanes.h (and what
// includes it) or lighting/shared/evsm.h links voxshadow::exact_fp, which passes the flags and defines
// VOXSHADOW_EXACT_FP. Only those headers include this one: the public API headers leave a consumer's flags
// alone.
#ifndef VOXSHADOW_EXACT_FP_H
#define VOXSHADOW_EXACT_FP_H
#ifndef VS_GLSL
#if defined(__FAST_MATH__)
#error "voxshadow's shared core cannot be compiled with -ffast-math: its results must round as the shader's do"
#endif
#if !defined(VOXSHADOW_EXACT_FP)
#error "voxshadow's shared core needs the exact floating-point flags: link voxshadow::exact_fp (CMake) or compile with -ffp-contract=off -fno-fast-math -DVOXSHADOW_EXACT_FP"
#endif
#endif
#endif
