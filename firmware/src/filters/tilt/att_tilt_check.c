/**
 * @file att_tilt_check.c
 * @brief att_tilt_settings_check (att_kinds.h): the first field of the settings that
 * att_tilt_settings_validate refuses, from the same table (att_tilt_checks.h); att_tilt_settings_rule:
 * the table's lines one by one. A source of its own, so
 * that it changes nothing in att_tilt.c's code (not even an inlining decision) and only an image that
 * calls att_filter_settings_check or att_filter_settings_rule links it.
 */
#include "../../math/att_fp.h"

#include "../att_kinds.h"
#include "att_tilt_checks.h"

#define ATT_TILT_WHY(name, ok, lo, hi, rule, unit) ATT_CHECK_WHY("tilt." name, ok, lo, hi, rule, unit)

att_status_t att_tilt_settings_check(const att_tilt_settings_t *s, att_settings_error_t *why)
{
    ATT_TILT_CHECKS(ATT_TILT_WHY)
    return ATT_OK;
}

#define ATT_TILT_RULE(name, ok, lo, hi, rule, unit) ATT_CHECK_RULE("tilt." name, ok, lo, hi, rule, unit)

att_status_t att_tilt_settings_rule(const att_tilt_settings_t *s, uint32_t index, att_settings_error_t *out)
{
    uint32_t line = 0u;
    ATT_TILT_CHECKS(ATT_TILT_RULE)
    return att_i_settings_end(out);
}
