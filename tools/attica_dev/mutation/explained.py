"""Survivors that cannot be killed, each with its reason (:data:`EXPLAINED`)."""

from __future__ import annotations

from dataclasses import dataclass

from attica_dev.mutation.mutants import Mutant


@dataclass(frozen=True)
class Explained:
    """A survivor with its reason: matched by file, the stripped source line, operator and change."""

    path: str
    source: str
    op: str
    change: str
    why: str


EXPLAINED: tuple[Explained, ...] = (
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
        (
            "equivalent: diag_ok only selects the fast path; att_mekf_repair tests every variance (cap, > 0)"
            " and the positive definiteness again and leaves a valid P unchanged, with no flag"
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
            "equivalent: the sum only tests that P and the angles are finite; a difference is finite "
            "exactly when the sum is (no overflow at these magnitudes)"
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
            "boundary: differs only when |cos(theta_mid)| equals cos_min exactly (then ctm is replaced "
            "by the same value, sign aside); no input lands there"
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
        (
            "rest = gyro_ok && accel_ok && att_i_vec3_dot(d, d) < c->rest_gyro2 && n2 > c->acc2_lo && n2 "
            "< c->acc2_hi;"
        ),
        "ROR",
        "< -> <=",
        "boundary: differs only when |w - b|^2 equals rest_gyro^2 exactly; no input lands there",
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
)
"""Survivors that no output can tell apart (equivalent mutants) or that only matter for states no input
reaches, each with its reason. A survivor not listed here is a gap: kill it with a test (or a case of
the oracle) or explain it here."""


OPEN: tuple[Explained, ...] = ()
"""Known gaps: survivors that a test could kill and none does yet, each saying which test would. The CI
slice tolerates them (and reports them); every other unexplained survivor fails it."""


def open_gap(m: Mutant) -> str:
    """The note :data:`OPEN` gives for a mutant ("" when none)."""
    for e in OPEN:
        if e.path == m.path and e.op == m.op and e.change == m.change and e.source == m.source:
            return e.why
    return ""


def explain(m: Mutant) -> str:
    """The reason :data:`EXPLAINED` gives for a mutant ("" when none)."""
    for e in EXPLAINED:
        if e.path == m.path and e.op == m.op and e.change == m.change and e.source == m.source:
            return e.why
    return ""
