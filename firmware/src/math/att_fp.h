/**
 * @file att_fp.h
 * @brief Private: floating-point environment rules for every attica source file.
 *
 * Include first in every firmware .c file. Contraction of a*b+c into fused multiply-add changes
 * results in the last bit, so it is off: by -ffp-contract=off on the command line (gcc, clang) and
 * by the standard pragma for compilers that honour it (clang; gcc ignores and warns about it).
 * GCC 12's vectorizers can still form fused multiply-add-subtract (vfmaddsub) from a*b +- c*d when
 * the target has FMA, despite -ffp-contract=off: cflags.txt therefore also turns vectorisation off.
 */
#ifndef ATT_FP_H
#define ATT_FP_H

#if defined(__clang__)
#pragma STDC FP_CONTRACT OFF
#endif

#if defined(__FAST_MATH__)
#error "attica must not be compiled with -ffast-math / -Ofast: results would not be reproducible"
#endif

#if defined(__FINITE_MATH_ONLY__) && (__FINITE_MATH_ONLY__ != 0)
#error "attica must not be compiled with -ffinite-math-only: NaN/Inf checks would be removed"
#endif

#if defined(__ASSOCIATIVE_MATH__) || defined(__RECIPROCAL_MATH__)
#error "attica must not be compiled with -fassociative-math / -freciprocal-math: results would change"
#endif

#if defined(__FLT_EVAL_METHOD__) && (__FLT_EVAL_METHOD__ != 0)
#error "attica needs FLT_EVAL_METHOD == 0 (float arithmetic evaluated in float, e.g. SSE not x87)"
#endif

#endif /* ATT_FP_H */
