/**
 * @file att_mars_check.c
 * @brief att_mars_settings_check (att_kinds.h): the first field of the settings that
 * att_mars_settings_validate refuses, from the same table (att_mars_checks.h); att_mars_settings_rule:
 * the table's lines one by one. A source of its own, so
 * that it changes nothing in att_mars.c's code (not even an inlining decision) and only an image that
 * calls att_filter_settings_check or att_filter_settings_rule links it.
 */
#include "../../math/att_fp.h"

#include "../att_kinds.h"
#include "att_mars_checks.h"

#define ATT_MARS_WHY(name, ok, lo, hi, rule, unit) ATT_CHECK_WHY("mars." name, ok, lo, hi, rule, unit)

att_status_t att_mars_settings_check(const att_mars_settings_t *s, att_settings_error_t *why)
{
    ATT_MARS_CHECKS(ATT_MARS_WHY)
    return ATT_OK;
}

#define ATT_MARS_RULE(name, ok, lo, hi, rule, unit) ATT_CHECK_RULE("mars." name, ok, lo, hi, rule, unit)

att_status_t att_mars_settings_rule(const att_mars_settings_t *s, uint32_t index, att_settings_error_t *out)
{
    uint32_t line = 0u;
    ATT_MARS_CHECKS(ATT_MARS_RULE)
    return att_i_settings_end(out);
}
