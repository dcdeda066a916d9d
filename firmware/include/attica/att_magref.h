/**
 * @file att_magref.h
 * @brief The reference magnetic field learnt over time, shared by att_mars and att_mekf: its norm and
 * dip follow the accepted samples, and a new field that stays steady becomes the reference.
 *
 * Each step with a known reference counts its magnetometer sample: accepted (it passed the norm and dip
 * tests against the reference m0) or rejected by them, summing |m| (uT) and the earth-frame vertical field
 * m'_z = (q m q*)_z (uT) of each group, in blocks of blk_n steps (1 s). At the end of a block:
 * - more accepted than rejected samples: the norm and sin(dip) of m0 move toward the block's means
 *   (sum |m| / n and sum m'_z / sum |m|) by the gain k_ref = T / (mag_ref_tau + T), T the block length
 *   (ref_on; the owner keeps m0's horizontal direction), and any candidate is dropped;
 * - otherwise the rejected samples' means are a candidate field: when the following blocks stay within
 *   half the rejection bounds of the candidate's running mean (norm within cand_tol_n of it relatively,
 *   sin(dip) within cand_tol_s) for new_n blocks, the candidate becomes m0 (the owner then speeds up its
 *   heading correction: a new field, a new heading reference).
 * Blocks without mag samples change nothing. The arithmetic is att_core.h's att_i_magref_*, mirrored by
 * host/attica/reference/magref.py. Units: uT; earth frame ENU.
 */
#ifndef ATT_MAGREF_H
#define ATT_MAGREF_H

#include "attica/att_config.h"
#include "attica/att_types.h"

#ifdef __cplusplus
extern "C" {
#endif

/* ATT_CDEF_BEGIN */
/** Coefficients of the learnt reference field, derived from the owner's settings. */
typedef struct {
    float k_ref;      /**< per-block gain of the reference's norm and sin(dip), [0, 1) (0: not learnt) */
    float cand_tol_n; /**< relative norm tolerance of a steady new field (mag_norm_reject / 2; Inf = none) */
    float cand_tol_s; /**< sin(dip) tolerance of a steady new field (mag_dip_reject / 2; Inf = none) */
    uint32_t blk_n;   /**< steps per block of the statistics (1 s, at least 1) */
    uint32_t new_n;   /**< steady blocks before a new field is adopted (0 = never) */
    bool ref_on;      /**< mag_ref_tau > 0: the reference's norm and dip follow the accepted samples */
} att_magref_params_t;

/** Statistics of the learnt reference field: this block's sums and the candidate new field. */
typedef struct {
    float acc_norm;  /**< sum of |m| of the accepted samples of this block, uT */
    float acc_z;     /**< sum of their vertical (earth z) field, uT */
    float rej_norm;  /**< sum of |m| of the samples rejected by norm or dip in this block, uT */
    float rej_z;     /**< sum of their vertical field, uT */
    float cand_norm; /**< candidate new reference: mean |m| of the steady rejected blocks, uT */
    float cand_sin;  /**< candidate's sin(dip): mean vertical / |m| of those blocks */
    uint32_t blk;    /**< steps of this block (since the reference was set) */
    uint32_t acc_n;  /**< accepted samples in this block */
    uint32_t rej_n;  /**< samples rejected by norm or dip in this block */
    uint32_t cand_n; /**< consecutive steady blocks of the candidate (0 = none) */
} att_magref_t;
/* ATT_CDEF_END */

#ifdef __cplusplus
}
#endif

#endif /* ATT_MAGREF_H */
