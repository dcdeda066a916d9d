/**
 * @file main.c
 * @brief The minimal main loop of docs/integration.md, with a simulated IMU so it runs on a PC.
 *
 * Three ways to build it (tests/test_cross.py and tests/test_examples.py build all three with the host
 * compiler and require the same printed bits):
 *
 *     cmake -S examples/c -B build/example && cmake --build build/example     # add_subdirectory
 *     cmake -S firmware -B build/fw && cmake --install build/fw --prefix /opt/attica
 *     cmake -S examples/c -B build/ex2 -DATTICA_EXAMPLE_FIND_PACKAGE=ON -DCMAKE_PREFIX_PATH=/opt/attica
 *     make -f examples/c/Makefile BUILD=build/example-mk                      # firmware/attica.mk
 */
#include <stdio.h>
#include <string.h>

#include "attica/attica.h"

static att_filter_t filter; /* state: static (no heap in attica) */

/* Stand-in for the IMU driver: level sensor turning about z at 0.2 rad/s, 100 Hz. */
static void read_imu(unsigned long i, att_sample_t *s)
{
    s->gyr.x = 0.0f;
    s->gyr.y = 0.0f;
    s->gyr.z = 0.2f;
    s->acc.x = 0.0f;
    s->acc.y = 0.0f;
    s->acc.z = 9.80665f + ((i % 2ul) ? 0.01f : -0.01f);
    s->mag.x = 0.0f; /* zero = no magnetometer sample */
    s->mag.y = 0.0f;
    s->mag.z = 0.0f;
}

static unsigned long bits(float f)
{
    unsigned int w;
    memcpy(&w, &f, sizeof w);
    return (unsigned long)w;
}

int main(void)
{
    att_filter_settings_t settings;
    att_sample_t in;
    att_output_t out;
    unsigned long i;
    if (att_filter_settings_default(ATT_FILTER_ARS, 0.01f, &settings) != ATT_OK) {
        return 1;
    }
    /* change what you need here, e.g. settings.ars.tau = 1.0f (a time constant > 0: the gain is unused) */
    if (att_filter_init(&filter, ATT_FILTER_ARS, &settings) != ATT_OK) {
        att_settings_error_t why; /* which field was refused, and its range */
        (void)att_filter_settings_check(ATT_FILTER_ARS, &settings, &why);
        printf("settings refused: %s must be in %s %s\n", why.field, why.rule, why.unit);
        return 1;
    }
    for (i = 0ul; i < 1000ul; i++) { /* in firmware: once per sample, in the IMU interrupt or main loop */
        read_imu(i, &in);
        (void)att_filter_step(&filter, &in, &out); /* fills q, gyro_bias, flags, steps */
    }
    att_filter_output(&filter, &out); /* on request: the whole record, Euler angles included */
    if ((out.valid & ATT_OUT_EULER) == 0u) { /* att_filter_step alone writes euler for ekf, gyro, tilt only */
        return 1;
    }
    printf("steps %lu flags 0x%04lx q %08lx %08lx %08lx %08lx yaw %.6f\n", (unsigned long)out.steps,
           (unsigned long)out.flags, bits(out.q.w), bits(out.q.x), bits(out.q.y), bits(out.q.z),
           (double)out.euler.z);
    return 0;
}
