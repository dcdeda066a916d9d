"""Survivors that cannot be killed, each with its reason (:data:`EXPLAINED`)."""

from __future__ import annotations

import functools
from dataclasses import dataclass
from pathlib import Path

from attica_dev.mutation.mutants import Mutant

ROOT = Path(__file__).resolve().parents[3]


@dataclass(frozen=True)
class Explained:
    """A survivor with its reason: matched by file, the stripped source line, operator and change.

    ``prev``, when given, is the stripped line above the mutant's (the last one that is not blank): for a
    line that occurs more than once (``return 0u;``), so that the reason covers that one place only.
    """

    path: str
    source: str
    op: str
    change: str
    why: str
    prev: str = ""


_DIAG_OK_COV = (
    "unproven: a test that reads a covariance instead of a variance can make diag_ok true while that "
    "variance is <= 0; att_mekf_pd then fails (a pivot is at most its variance), but "
    "att_mekf_repair(diag_ok true) skips the reset of that variance to its cap, so the state would differ. "
    "Equivalent only if no variance <= 0 reaches step 4, which the rounding of the rest update does not "
    "rule out"
)
"""The reason shared by the mekf's diag_ok tests that a mutant makes read a covariance."""

EXPLAINED: tuple[Explained, ...] = (
    Explained(
        "firmware/src/core/att_core.h",
        "} else if (r->rej_n > 0u && p->new_n > 0u && r->rej_norm > 0.0f) {",
        "ROR",
        "> -> >=",
        (
            "boundary: rej_norm is the sum of |m| of the block's rejected valid samples, > 0 whenever "
            "rej_n > 0 unless every one of their norms underflows to 0 (a vector below about 1e-19 uT, "
            "which the sample check passes as valid); rej_n >= 0 is then caught by rej_norm > 0, and "
            "rej_norm >= 0 only differs for those underflowing samples (their candidate 0 / 0 is then "
            "compared and dropped)"
        ),
    ),
    Explained(
        "firmware/src/filters/ekf/att_ekf.c",
        "const float sum = ((((((((((((((((((p[0] + p[1]) + p[3]) + p[4]) + p[5]) + p[6]) + p[8]) + p[9])"
        " + p[10]) +",
        "CONST",
        "8 -> 9",
        (
            "unreachable: the finiteness probe of P sums its elements, and p[8] (cov(theta, b_x)) is never "
            "non-finite alone at the probe: the step's prediction spreads it into p[6] (var(theta)) first "
            "(a state poked with NaN in p[8] alone still restarts P, NUMERIC, after one step)"
        ),
    ),
    Explained(
        "firmware/src/filters/mars/att_mars.c",
        "st->flags |= ATT_FLAG_MAG_REJECTED;",
        "BIT",
        "|= -> &=",
        (
            "unreachable: att_mars_set_m0 fails only for |m0|^2 < 2^-100 or a non-finite m0, and this m0 "
            "is a rotation of a mag sample that passed the sensor check (finite, |m|^2 >= 2^-100)"
        ),
    ),
    Explained(
        "firmware/src/filters/mekf/att_mekf.c",
        "p[ATT_MEKF_IX(0u, 0u)] > 0.0f && p[ATT_MEKF_IX(1u, 1u)] > 0.0f &&",
        "CONST",
        "0.0f -> 1.0f",
        (
            "equivalent: diag_ok only selects the fast path; att_mekf_repair tests every variance (cap, > 0)"
            " and the positive definiteness again and leaves a valid P unchanged, with no flag"
        ),
    ),
    Explained(
        "firmware/src/filters/mekf/att_mekf.c",
        "p[ATT_MEKF_IX(4u, 4u)] > 0.0f && p[ATT_MEKF_IX(5u, 5u)] > 0.0f;",
        "CONST",
        "4u -> 5u",
        _DIAG_OK_COV,
    ),
    Explained(
        "firmware/src/filters/mekf/att_mekf.c",
        "p[ATT_MEKF_IX(2u, 2u)] > 0.0f && p[ATT_MEKF_IX(3u, 3u)] > 0.0f &&",
        "CONST",
        "3u -> 4u",
        _DIAG_OK_COV,
    ),
    Explained(
        "firmware/src/filters/mekf/att_mekf.c",
        "p[ATT_MEKF_IX(2u, 2u)] > 0.0f && p[ATT_MEKF_IX(3u, 3u)] > 0.0f &&",
        "ZERO",
        "3u -> 0u",
        _DIAG_OK_COV,
    ),
    Explained(
        "firmware/src/filters/mekf/att_mekf.c",
        "p[ATT_MEKF_IX(4u, 4u)] > 0.0f && p[ATT_MEKF_IX(5u, 5u)] > 0.0f;",
        "CONST",
        "5u -> 6u",
        _DIAG_OK_COV + "; (5, 6) also reads p[21], past P",
    ),
    Explained(
        "firmware/src/filters/mekf/att_mekf.c",
        "k = 0.0f;",
        "CONST",
        "0.0f -> 1.0f",
        (
            "unproven: needs a NaN |V|^2 of the scale sensitivity; V is bounded by 16 at every step start, "
            "a NaN would need an overflow inside one update (det S near the smallest float); neither "
            "reached nor proven unreachable"
        ),
    ),
    Explained(
        "firmware/src/calib/att_calib.c",
        "if (model_identity && r > 0u) {",
        "CONST",
        "0u -> 1u",
        (
            "equivalent: remap 1 is the identity, so with an identity model it returns through the "
            "model_identity && mount_identity branch above; r > 0 and r > 1 select the same cases here"
        ),
    ),
    Explained(
        "firmware/src/calib/att_calib.c",
        "if (index < 15u) {",
        "ROR",
        "< -> <=",
        (
            "equivalent: index 15 returns from the accel-matrix branch above (index >= 15 && index < 24) "
            "and never reaches this test"
        ),
    ),
    Explained(
        "firmware/src/can/att_can.c",
        "m.crc = 0u;",
        "DEL",
        "m.crc = 0u; -> ;",
        (
            "equivalent: the packed CRC byte is overwritten by att_can_seal before the frame leaves the "
            "encoder"
        ),
    ),
    Explained(
        "firmware/src/can/att_can.c",
        "m.crc = 0u;",
        "CONST",
        "0u -> 1u",
        (
            "equivalent: the packed CRC byte is overwritten by att_can_seal before the frame leaves the "
            "encoder"
        ),
    ),
    Explained(
        "firmware/src/core/att_core.h",
        "if (!(n2 >= ATT_NORM2_MIN)) {",
        "ROR",
        ">= -> >",
        (
            "boundary: differs only for a low-passed specific force of exactly |v|^2 = 2^-100 (|v| = "
            "2^-50 m/s^2) reaching att_i_align_up; no input of the suite or the oracle lands on that "
            "float"
        ),
    ),
    Explained(
        "firmware/src/core/att_core.h",
        (
            "#define ATT_ROTVEC_Z_SMALL 0x1p-4f /* |rv|^2 up to which the series of "
            "att_i_quat_from_rotvec_fast hold */"
        ),
        "CONST",
        "0x1p-4f -> 0x1.000002p-4f",
        (
            "boundary: moves the series/exact switch by one float (|rv|^2 = 1/16 + 2^-28 only); both "
            "paths agree within 1 ulp there (tests/c/att_core_test.c) and no step's rotation vector has "
            "that square norm"
        ),
    ),
    Explained(
        "firmware/src/core/att_core.h",
        "#define ATT_ROTVEC_C2 0x1.555556p-9f     /* 1/384 */",
        "CONST",
        "0x1.555556p-9f -> 0x1.555558p-9f",
        (
            "below output precision: the z^2/384 term (z <= 1/16) moves by < 2e-11, under half an ulp of "
            "the cosine (~1); no rounding of the sum changed on any input"
        ),
    ),
    Explained(
        "firmware/src/filters/ars/att_ars.c",
        "flags |= ATT_FLAG_NUMERIC; /* keep the attitude and the low-pass states from before */",
        "BIT",
        "|= -> &=",
        (
            "unreachable: the product of the unit correction qc and the normalised q always passes "
            "att_i_quat_normalize_bounded (the suite does not reach this line either)"
        ),
    ),
    Explained(
        "firmware/src/filters/att_filter.c",
        "f->cal.acc_body = att_i_vec3(0.0f, 0.0f, 0.0f);",
        "CONST",
        "0.0f -> 1.0f",
        (
            "dead store: reset clears have_acc, acc_body is read only when have_acc, and the next step "
            "writes it before setting have_acc"
        ),
    ),
    Explained(
        "firmware/src/filters/att_filter.c",
        "out->flags = 0u;",
        "DEL",
        "out->flags = 0u; -> ;",
        (
            "dead store: every caller of att_filter_clear fills the record through the kind's hook, "
            "which writes flags"
        ),
    ),
    Explained(
        "firmware/src/filters/ekf/att_ekf.c",
        (
            "#define ATT_EKF_SETTLED 0x1.47ae14p-7f       /* (0.1 rad)^2: the tilt error (sin^2) that "
            "ends the convergence phase */"
        ),
        "CONST",
        "0x1.47ae14p-7f -> 0x1.47ae16p-7f",
        (
            "boundary: a threshold one ulp higher; only a tilt-error ratio within 2^-24 of it would end "
            "the convergence phase one step earlier; no input lands there"
        ),
    ),
    Explained(
        "firmware/src/filters/ekf/att_ekf.c",
        "#define ATT_EKF_INC_S3 (-0x1.555556p-3f) /* -1/6 */",
        "CONST",
        "0x1.555556p-3f -> 0x1.555558p-3f",
        (
            "below output precision: the d^3/6 term (d <= 1/16 rad) moves by < 5e-12, under half an ulp "
            "of the sine increments; no rounding changed on any input"
        ),
    ),
    Explained(
        "firmware/src/filters/ekf/att_ekf.c",
        "a = (a - 0x1.921fb6p+2f) - (-0x1.777a5cp-23f);",
        "CONST",
        "0x1.777a5cp-23f -> 0x1.777a5ep-23f",
        (
            "below output precision: the low part of 2 pi moves by 2^-47 rad, under half an ulp of every "
            "wrapped angle above 1e-7 rad"
        ),
    ),
    Explained(
        "firmware/src/filters/ekf/att_ekf.c",
        (
            "const float sum = ((((((((((((((((((p[0] + p[1]) + p[3]) + p[4]) + p[5]) + p[6]) + p[8]) + "
            "p[9]) + p[10]) +"
        ),
        "AOR",
        "+ -> -",
        (
            "equivalent in reachable states: the sum only tests that P and the angles are finite; a "
            "difference is finite exactly when the sum is as long as no two terms near 1e38 meet (one step "
            "grows a variance to about 1e29 at most, and P is capped again at every step without an "
            "update); this holds for every `+` of the line"
        ),
    ),
    Explained(
        "firmware/src/filters/ekf/att_ekf.c",
        (
            "const float sum = ((((((((((((((((((p[0] + p[1]) + p[3]) + p[4]) + p[5]) + p[6]) + p[8]) + "
            "p[9]) + p[10]) +"
        ),
        "CONST",
        "5 -> 6",
        (
            "equivalent in reachable states: p[5] (a correlation) is non-finite only together with the "
            "variances it is computed from, which the sum still holds"
        ),
    ),
    Explained(
        "firmware/src/filters/ekf/att_ekf.c",
        (
            "const float sum = ((((((((((((((((((p[0] + p[1]) + p[3]) + p[4]) + p[5]) + p[6]) + p[8]) + "
            "p[9]) + p[10]) +"
        ),
        "ZERO",
        "10 -> 0",
        (
            "equivalent in reachable states: p[10] (a correlation) is non-finite only together with the "
            "variances it is computed from, which the sum still holds"
        ),
    ),
    Explained(
        "firmware/src/filters/ekf/att_ekf.c",
        (
            "return att_i_isfinitef(sum) && p[0] > 0.0f && p[6] > 0.0f && p[11] > 0.0f && p[15] > 0.0f "
            "&& p[18] > 0.0f &&"
        ),
        "ROR",
        "> -> >=",
        (
            "unreachable: the yaw variance p[11] starts at p0 > 0 and only grows (q_psi dt added every "
            "step, yaw is never measured), so it is never exactly 0"
        ),
    ),
    Explained(
        "firmware/src/filters/ekf/att_ekf.c",
        "if (att_i_absf(ctm) < c->cos_min) {",
        "ROR",
        "< -> <=",
        (
            "equivalent: the guard's branch (lines 546-548) sets no flag; at |ctm| == cos_min (> 0) the "
            "replacement (ctm < 0 ? -cos_min : cos_min) is ctm itself, bit for bit"
        ),
    ),
    Explained(
        "firmware/src/filters/ekf/att_ekf.c",
        "s->r_accel = 0.0f;",
        "DEL",
        "s->r_accel = 0.0f; -> ;",
        "equivalent: the seed preset starts from att_ekf_settings_default, whose r_accel is already 0",
    ),
    Explained(
        "firmware/src/filters/gyro/att_gyro.c",
        "e.y = att_i_clampf(e.y, -ATT_PIO2_F, ATT_PIO2_F);",
        "DEL",
        "e.y = att_i_clampf(e.y, -ATT_PIO2_F, ATT_PIO2_F); -> ;",
        (
            "equivalent: theta = atan2(-m20, cps m00 + sps m10) where cps and sps take the signs of m00 "
            "and m10, so x >= 0 and theta is already within [-pi/2, pi/2]"
        ),
    ),
    Explained(
        "firmware/src/filters/mars/att_mars.c",
        "st->dip_hi = 0.0f;",
        "DEL",
        "st->dip_hi = 0.0f; -> ;",
        "dead store: the dip limits are read only once m0 is valid, and att_mars_m0_limits sets them then",
    ),
    Explained(
        "firmware/src/filters/mars/att_mars.c",
        (
            "if (accel_ok && c->reject_on && att_i_absf(att_i_sqrtf(n2) / c->gravity - 1.0f) > "
            "c->accel_reject) {"
        ),
        "CONST",
        "1.0f -> 0x1.000002p+0f",
        (
            "boundary: moves the rejection band by 2^-23 g; only |a| within 1.2e-7 g of the band's edge "
            "sees it"
        ),
    ),
    Explained(
        "firmware/src/filters/mekf/att_mekf.c",
        "#define ATT_MEKF_UNROLL ATT_MEKF_PRAGMA(GCC unroll 6)",
        "ZERO",
        "6 -> 0",
        (
            "equivalent: unrolling changes the code, not the arithmetic (the same operations in the same "
            "order; no reassociation without fast-math)"
        ),
    ),
    Explained(
        "firmware/src/filters/mekf/att_mekf.c",
        "st->dip_hi = 2.0f;",
        "CONST",
        "2.0f -> 0x1.000002p+1f",
        "equivalent: 2 means no upper dip limit (sin(dip) <= 1); 2 + 2^-22 is the same no limit",
    ),
    Explained(
        "firmware/src/filters/mekf/att_mekf.c",
        (
            "if (mnorm < st->m0_lo || mnorm > st->m0_hi || me.z < st->dip_lo * mnorm || me.z > "
            "st->dip_hi * mnorm) {"
        ),
        "ROR",
        "> -> >=",
        "boundary: differs only when |m| equals the upper norm limit exactly; no input lands there",
    ),
    Explained(
        "firmware/src/filters/mekf/att_mekf.c",
        ("rest = gyro_ok && accel_ok && att_i_vec3_dot(d, d) < gate && n2 > c->acc2_lo && n2 < c->acc2_hi;"),
        "ROR",
        "< -> <=",
        (
            "boundary: differs only when |w - b|^2 equals the gate (rest_gyro^2 + 9 tr(P_bb)) exactly; no "
            "input lands there"
        ),
    ),
    Explained(
        "firmware/src/node/att_node.c",
        "return 8u * n + 47u + (34u + 8u * n - 1u) / 4u;",
        "ZERO",
        "1u -> 0u",
        "equivalent: 34 + 8n is 2 mod 4, so floor((33 + 8n) / 4) = floor((34 + 8n) / 4) for every n",
    ),
    Explained(
        "firmware/src/node/att_node.c",
        "memset(s, 0, sizeof *s);",
        "CONST",
        "0 -> 1",
        (
            "equivalent: every field is assigned after the memset; only padding and the bytes of the "
            "settings union beyond the selected kind's member differ"
        ),
    ),
    Explained(
        "firmware/src/node/att_node.c",
        "s->data_bitrate = 0u;",
        "DEL",
        "s->data_bitrate = 0u; -> ;",
        "equivalent: the memset above already zeroed it",
    ),
    Explained(
        "firmware/src/node/att_node.c",
        "s->fd = false;",
        "DEL",
        "s->fd = false; -> ;",
        "equivalent: the memset above already zeroed it",
    ),
    Explained(
        "firmware/src/node/att_node.c",
        "if (!(load >= 0.0f) || load > 1.0f) {",
        "ROR",
        ">= -> >",
        (
            "unreachable: a validated node's load is a positive rate times a positive frame time, never "
            "exactly 0"
        ),
    ),
    Explained(
        "firmware/src/filters/mekf/att_mekf.c",
        "st->mag_hy = 0.0f;",
        "CONST",
        "0.0f -> 1.0f",
        (
            "never read: att_mekf_m0_limits overwrites it when m0 has a horizontal part; without one, m0_lo "
            "is Inf and every sample is rejected before the correction reads mag_hx / mag_hy (the reset's "
            "copy of the line is the same: m0_valid is false until the limits are derived)"
        ),
    ),
    Explained(
        "firmware/src/node/att_node.c",
        "return (a > 255u || b > 255u - a) ? 255u : a + b;",
        "ROR",
        "> -> >=",
        "equivalent: at a = 255 both sides give 255 (255 + 0 or the saturation)",
    ),
    Explained(
        "firmware/src/node/att_node.c",
        "return (a > 255u || b > 255u - a) ? 255u : a + b;",
        "CONST",
        "255u -> 256u",
        "unreachable: a is the running saturated total (<= 255), never 256 or more",
    ),
    Explained(
        "firmware/src/filters/mars/att_mars.c",
        "st->m0_perp = zero;",
        "DEL",
        "st->m0_perp = zero; -> ;",
        (
            "dead store: att_mars_reset clears m0_valid; m0_perp is read only by att_mars_mag_correct, which "
            "runs only with m0_valid (att_mars_mag_step), and m0_valid becomes true only in att_mars_set_m0, "
            "which calls att_mars_m0_limits, and that writes m0_perp on both of its paths (FULL: perp; "
            "HORIZONTAL: up); att_mars_yaw_to only rotates the stale value, which is overwritten before "
            "a read"
        ),
    ),
    Explained(
        "firmware/src/filters/mekf/att_mekf.c",
        "st->mag_hx = 0.0f;",
        "CONST",
        "0.0f -> 1.0f",
        (
            "never read: att_mekf_m0_limits overwrites it when m0 has a horizontal part; without one, m0_lo "
            "is Inf and every sample is rejected (att_mekf_heading) before att_mekf_mag_apply reads mag_hx / "
            "mag_hy (the reset's copy of the line is the same: m0_valid is false until the limits are "
            "derived; att_mekf_yaw_to only rotates the pair)"
        ),
    ),
    Explained(
        "firmware/src/filters/mekf/att_mekf.c",
        "if (!(add <= c->p_max)) {",
        "ROR",
        "<= -> <",
        (
            "equivalent: the two differ only for add == p_max, where the mutant's branch stores p_max, the "
            "value add already holds (p_max > 0: the same bits); NaN takes the branch either way"
        ),
    ),
    Explained(
        "firmware/src/filters/mekf/att_mekf.c",
        (
            "if (n <= ATT_MEKF_SENS_MAX * ATT_MEKF_SENS_MAX && st->p_scale >= 0.0f && st->scale <= "
            "ATT_MEKF_SCALE_MAX &&"
        ),
        "AOR",
        "* -> /",
        (
            "equivalent: the mutant also calls att_mekf_scale_limit for 1 < |V|^2 <= 256 with the scale and "
            "p_scale in range; there it sets no flag and changes nothing (no clamp; k stays 1, V[i] * 1 = "
            "V[i] bit for bit)"
        ),
    ),
    Explained(
        "firmware/src/can/att_can.c",
        "g.crc = 0u;",
        "CONST",
        "0u -> 1u",
        (
            "equivalent: att_can_db_imu_gyro_pack puts the crc field in data[0] only, and att_can_seal "
            "(att_can.c:225) overwrites data[0] with the CRC of data[1..7] (IMU_GYRO has a CRC, len 8 from "
            "att_can_frame_start) before the frame leaves the encoder"
        ),
    ),
    Explained(
        "firmware/src/core/att_core.h",
        "if (att_i_absf(gyr.x) <= range && att_i_absf(gyr.y) <= range && att_i_absf(gyr.z) <= range) {",
        "ROR",
        "<= -> <",
        (
            "equivalent: the test only selects the fast path; at |w_z| == range (x, y within range) the "
            "slow path finds the sample finite and no component > range and returns 0 too (att_core.h:29-35)"
        ),
    ),
    Explained(
        "firmware/src/core/att_core.h",
        "if (!att_i_vec3_isfinite(acc) || !(n2 >= ATT_NORM2_MIN)) {",
        "ROR",
        ">= -> >",
        (
            "equivalent in reachable states: differs only at |a|^2 == 2^-100 exactly, which passes the "
            "fast test above (n2 >= 2^-100 && n = 2^-50 <= range) unless range < 2^-50; the only caller, "
            "att_tilt_step, passes accel_range > gravity >= 1 (att_tilt_checks.h)"
        ),
    ),
    Explained(
        "firmware/src/core/att_core.h",
        "return (n > range) ? ATT_FLAG_ACCEL_RANGE : 0u;",
        "CONST",
        "0u -> 1u",
        (
            "unreachable: this line is reached with a finite sample (n2 finite or +Inf, n never NaN) and "
            "n2 >= 2^-100, so the fast test failed on n <= range: n > range always holds and the 0u arm "
            "is never taken (range is tilt's validated accel_range, not NaN)"
        ),
    ),
    Explained(
        "firmware/src/core/att_core.h",
        "if (*rest_count > p->rest_n) {",
        "ROR",
        "> -> >=",
        "equivalent: at *rest_count == rest_n the limiting assignment stores the value already there",
    ),
    Explained(
        "firmware/src/core/att_sensor.c",
        "if (ratio > ATT_SAMPLES_MAX) {",
        "ROR",
        "> -> >=",
        "equivalent: at ratio == 2^24 the clamp assigns ratio the value it already has",
    ),
    Explained(
        "firmware/src/filters/att_filter.c",
        "if (len > 0u) {",
        "CONST",
        "0u -> 1u",
        (
            "equivalent: at both tests (before a name's '|' and before the unknown bits' '|') len is 0 or "
            'the length of the names so far, at least 6 (the shortest of att_flag_names, "GIMBAL"), '
            "never 1"
        ),
    ),
    Explained(
        "firmware/src/node/att_node.c",
        "return 8u * n + 47u + (34u + 8u * n - 1u) / 4u;",
        "CONST",
        "1u -> 2u",
        "equivalent: (33 + 8n) / 4 and (32 + 8n) / 4 are both 8 + 2n in integer division (n <= 8)",
    ),
    Explained(
        "firmware/src/node/att_node.c",
        "return 0u;",
        "CONST",
        "0u -> 1u",
        (
            "unreachable: the failed att_can_decode_imu_part of att_node_part: att_node_handle passes only "
            "IMU_GYRO/ACC/MAG frames that passed att_can_check, whose length test (att_can.c:152) makes "
            "len == 8, and the decoder fails only for NULL, len < 8 or another ID"
        ),
        prev="if (!att_can_decode_imu_part(f, &v)) {",
    ),
    Explained(
        "firmware/src/node/att_node.c",
        "return 0u;",
        "CONST",
        "0u -> 1u",
        (
            "unreachable: the default arm of att_can_check's result in att_node_handle: every ID admitted "
            "there has a length in att_can_msg_len, so ERR_UNKNOWN_ID (the only other result) never comes"
        ),
        prev="n->stats.unknown_ids++;",
    ),
    Explained(
        "firmware/src/node/att_node.c",
        "n->f.cal.have_acc = false;",
        "DEL",
        "n->f.cal.have_acc = false; -> ;",
        (
            "dead store: have_acc is read only by att_filter_accel in att_node_emit, which runs after "
            "att_node_step's att_filter_step_n (periods >= 1); with ATT_CALIB_ACTIVE_ACC set every step "
            "goes through att_filter_step_cal, which sets acc_body and have_acc first (att_filter.c:324), "
            "and without it att_filter_accel returns before reading them"
        ),
    ),
    Explained(
        "firmware/src/filters/ekf/att_ekf.c",
        "for (i = 0; i < 21; i++) {",
        "ROR",
        "< -> <=",
        (
            "never read: the extra store p[21] = 0 of att_ekf_p_diag lands on st->lp1.x (the member after "
            "p[21] in att_ekf_state_t); att_ekf_reset and att_ekf_start write lp1 right after it, and after "
            "att_ekf_p_restart the step is NUMERIC (initialised false): the next step that reads lp1 runs "
            "att_ekf_start first, which writes lp1 and lp2 (lines 1022-1023); yaw_to refuses until then"
        ),
    ),
    Explained(
        "firmware/src/filters/ekf/att_ekf.c",
        "f->st.lp1 = att_i_vec3(0.0f, 0.0f, f->c.gravity);",
        "DEL",
        "f->st.lp1 = att_i_vec3(0.0f, 0.0f, f->c.gravity); -> ;",
        (
            "dead store: reset leaves lp_ready false; st->lp1 is then read only by att_ekf_turn into the "
            "update's copy, which line 829 overwrites while !ready (and by yaw_to, which only turns it); "
            "lp_ready turns true only in att_ekf_start and att_ekf_commit, which write lp1 and lp2 first"
        ),
    ),
    Explained(
        "firmware/src/filters/ekf/att_ekf.c",
        "f->st.lp2 = f->st.lp1;",
        "DEL",
        "f->st.lp2 = f->st.lp1; -> ;",
        (
            "dead store: reset leaves lp_ready false; st->lp2 is then read only by att_ekf_turn into the "
            "update's copy, which line 830 overwrites while !ready (and by yaw_to, which only turns it); "
            "lp_ready turns true only in att_ekf_start and att_ekf_commit, which write lp1 and lp2 first"
        ),
    ),
    Explained(
        "firmware/src/filters/ekf/att_ekf.c",
        "for (i = 0; i < 6; i++) {",
        "ROR",
        "< -> <=",
        (
            "equivalent: at lines 326, 335 and 341 the extra pass i = 6 runs an empty inner loop (j = i or "
            "i + 1 is not < 6); the copy at line 317 does not compile (-Waggressive-loop-optimizations)"
        ),
    ),
    Explained(
        "firmware/src/filters/ekf/att_ekf.c",
        "float dd[2] = {0.0f, 0.0f};",
        "CONST",
        "0.0f -> 1.0f",
        (
            "never read: with usable rates att_ekf_propagate writes dd[0], dd[1] (lines 551-552) before any "
            "read; without, the kept angles are canonical (|theta| <= pi/2: no flip) and added is true, so "
            "att_ekf_predict_trig, dd's only reader, is not called"
        ),
    ),
    Explained(
        "firmware/src/filters/ekf/att_ekf.c",
        "att_ekf_sincos_step(e.y, 0.0f, t0.sth, t0.cth, &tr->sth, &tr->cth);",
        "CONST",
        "0.0f -> 1.0f",
        (
            "equivalent: d = 1 takes att_i_sincosf(e.y) with e.y = st->euler.y, the call that gave t0 "
            "(line 655); d = 0 gives sd = +0, cd = 1, so s = s0 + c0 (+0) = s0 (s0 is +0 only at theta = "
            "+-0, where att_i_sin_poly gives +0 and c0 = 1) and c = c0 - s0 (+0) = c0 (c0 != 0 for "
            "|theta| <= pi/2 in float32): the same bits"
        ),
    ),
    Explained(
        "firmware/src/filters/ekf/att_ekf.c",
        "if (!att_i_isfinitef((e.x + e.y) + e.z)) {",
        "AOR",
        "+ -> -",
        (
            "equivalent: after att_ekf_canon each angle is NaN or within [-pi, pi] (att_ekf_wrap: one step "
            "of 2 pi, else att_wrap_pi, NaN beyond 8192 rad or not finite; the flip maps theta within), so "
            "any sum or difference of the three is finite exactly when all three are"
        ),
    ),
    Explained(
        "firmware/src/filters/ekf/att_ekf.c",
        "const float sum = ((((((((((((((((((p[0] + p[1]) + p[3]) + p[4]) + p[5]) + p[6]) + p[8]) + p[9])"
        " + p[10]) +",
        "CONST",
        "0 -> 1",
        (
            "unproven: the probe without p[0] (roll's variance) differs only for a p[0] of +Inf alone; one "
            "step grows it to about 1e29 at most and every step without an accel update caps P again, so "
            "an overflow would need a build-up over several steps with updates near the pole; not built"
        ),
    ),
    Explained(
        "firmware/src/filters/ekf/att_ekf.c",
        "p[11]) + p[15]) + p[16]) + p[17]) + p[18]) + p[19]) + p[20]) + e.x) + e.y) + e.z);",
        "ZERO",
        "16 -> 0",
        (
            "unproven: p[0] counted twice instead of p[16] differs only when 2 p[0] overflows (p[0] "
            "between 1.7e38 and FLT_MAX) or p[16] alone is not finite; neither reached (see the 0 -> 1 "
            "entry of the line above)"
        ),
    ),
    Explained(
        "firmware/src/node/att_node.c",
        "if (!(load >= 0.0f) || load > 1.0f) {",
        "CONST",
        "1.0f -> 0x1.000002p+0f",
        (
            "boundary: accepts a bus load in (1, 1 + 2^-23] as well; a load is rates times frame times "
            "summed in float32, and no configuration of the oracle lands in that one-ulp band above 1"
        ),
    ),
    Explained(
        "firmware/src/core/att_core.h",
        "for (k = i + 1; k < j; k++) {",
        "CONST",
        "1 -> 2",
        (
            "unproven: the row of L^-1 without its first inner term changes the rounding bound s_j of the "
            "pivot test (att_i_pd6, the ekf's and the mekf's), which changes the verdict only for a pivot "
            "between the two thresholds margin s_j; the F16 stream and the 200 near-singular states of "
            "edges:mekf:pd do not land there (judged on the mekf's copy; since the test is shared the ekf's "
            "tests run against it too, not yet in a mutation run)"
        ),
    ),
)
"""Survivors that no output can tell apart (equivalent mutants) or that only matter for states no input
reaches, each with its reason. A survivor not listed here is a gap: kill it with a test (or a case of
the oracle) or explain it here."""


OPEN: tuple[Explained, ...] = (
    Explained(
        "firmware/src/filters/att_filter.c",
        "text[10] = '\\0';",
        "DEL",
        "text[10] = '\\0'; -> ;",
        (
            "undefined behaviour, not seen by the oracle: text[10] is then read uninitialised, a byte of "
            "the stack below the caller; through cffi (and libffi) the call comes right after "
            "PyEval_SaveThread, which leaves 0 there, so the text ends where it should. A C test (stage A) "
            "that calls att_flags_format with unknown bits after a call that leaves non-zero bytes in that "
            "stack slot, or the suite under MSan/valgrind, would kill it"
        ),
    ),
)
"""Known gaps: survivors that a test could kill and none does yet, each saying which test would. The CI
slice tolerates them (and reports them); every other unexplained survivor fails it."""


@functools.cache
def _lines(path: str) -> tuple[str, ...]:
    return tuple(line.strip() for line in (ROOT / path).read_text().splitlines())


def line_before(m: Mutant) -> str:
    """The stripped line above the mutant's line in the checkout (the last one that is not blank)."""
    lines = _lines(m.path)
    for i in range(m.line - 2, -1, -1):
        if lines[i]:
            return lines[i]
    return ""


def matches(e: Explained, m: Mutant) -> bool:
    """``e`` names ``m``: the same file, line, operator and change (and the line above, if ``e.prev``)."""
    same = e.path == m.path and e.op == m.op and e.change == m.change and e.source == m.source
    return same and (not e.prev or line_before(m) == e.prev)


def open_gap(m: Mutant) -> str:
    """The note :data:`OPEN` gives for a mutant ("" when none)."""
    for e in OPEN:
        if matches(e, m):
            return e.why
    return ""


PROVEN = (
    "equivalent:",
    "equivalent in reachable states:",
    "unreachable:",
    "dead store:",
    "never read:",
)
"""How an explanation that proves a mutant equivalent begins: no input the contracts accept can tell it
from the original. Such a survivor is an equivalent mutant, which the score leaves out as it leaves out
the mutants with the same object code. The other reasons ("boundary:", "below output precision:") name
mutants a test could kill in principle; "unproven:" survivors neither killed nor proven equivalent.
Those stay survivors in the score."""


def is_proven(why: str) -> bool:
    """True when an explanation proves its mutant equivalent (:data:`PROVEN`)."""
    return why.startswith(PROVEN)


def explain(m: Mutant) -> str:
    """The reason :data:`EXPLAINED` gives for a mutant ("" when none)."""
    for e in EXPLAINED:
        if matches(e, m):
            return e.why
    return ""
