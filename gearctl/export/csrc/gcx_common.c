/* SPDX-License-Identifier: MIT -- part of gearctl, written for it. */
/* Helpers shared by the exported controllers (gcx_pid.c, gcx_mpc.c). Every function is static: an exported
 * controller's translation unit has two external symbols, gearctl_ctrl_init and gearctl_ctrl_step (the MPC's
 * QP solver, gearctl_qp.c, adds its gearctl_qp_* functions). */

#if defined(__GNUC__) || defined(__clang__)
#define GCX_FN static __attribute__((unused)) /* a kind uses only part of its family's functions */
#else
#define GCX_FN static
#endif

#include <float.h>
#include <stdint.h>
#include <string.h>

#if DBL_MANT_DIG != 53 || DBL_MAX_EXP != 1024
#error "gearctl: the exported controller needs IEEE 754 binary64 doubles (DBL_MANT_DIG 53, DBL_MAX_EXP 1024)"
#endif
/* ... and every double operation rounded to double: with x87 excess precision (FLT_EVAL_METHOD 2: 32-bit x86 without
 * SSE2 arithmetic, gcc -mfpmath=387) make check found 3471 of 4000 steps of a dead-zone inverse off the Python torques
 * by up to 7.8e-6 relative, after a build that said nothing */
#if defined(FLT_EVAL_METHOD) && FLT_EVAL_METHOD == 2
#error "gearctl: the exported controller needs double arithmetic evaluated in double (FLT_EVAL_METHOD 0), not x87 excess precision: build 32-bit x86 with -msse2 -mfpmath=sse"
#endif

/* No fused multiply-adds: the Python controller rounds every product. GCC's ISO mode (-std=c99) contracts nothing,
 * but clang contracts within an expression in every mode (-ffp-contract=on) wherever the target has FMA (x86-64 with
 * -march=native, any AArch64): make check then found 3439 of 4000 steps off by up to 7e-14 relative. GCC ignores
 * this standard pragma (and warns with -Wall), so it is given where it is honoured. */
#if defined(__clang__) || !defined(__GNUC__)
#pragma STDC FP_CONTRACT OFF
#endif

/* x is finite, read off its bits: isfinite(x) and x == x are folded to 1 under -ffast-math or -ffinite-math-only,
 * which would let a NaN reading through the input check */
GCX_FN int gcx_finite(double x) {
    uint64_t bits;
    memcpy(&bits, &x, sizeof bits);
    return (bits & UINT64_C(0x7ff0000000000000)) != UINT64_C(0x7ff0000000000000);
}

#define GCX_PI 3.141592653589793
/* the largest int (without <limits.h>): a counter that is only compared with a bound stops there. Python's ints
 * never overflow; a C int counting samples would after 2^31 of them (25 days at 1 kHz), undefined behaviour */
#define GCX_INT_MAX ((int)(~0u >> 1))
#define GCX_HALF_PI 1.5707963267948966        /* Python: 0.5 * math.pi */
#define GCX_HALF_PI_SQ 4.934802200544679      /* Python: 0.5 * math.pi ** 2 */

/* Python's min(a, b) and max(a, b) (the first argument unless the second is strictly beyond it) */
GCX_FN double gcx_min(double a, double b) { return b < a ? b : a; }
GCX_FN double gcx_max(double a, double b) { return b > a ? b : a; }

