/**
 * @file att_host_node.c
 * @brief Host-only batch helpers for the CAN codec and node (see att_host_node.h).
 */
#include "att_host_node.h"

size_t att_host_node_run(att_node_t *node, const att_can_frame_t *in, size_t n_in, att_can_frame_t *out,
                         size_t max_out, size_t *n_out)
{
    size_t i;
    size_t k = 0u;
    size_t steps = 0u;
    if (node == NULL || in == NULL || out == NULL || n_out == NULL) {
        return 0u;
    }
    for (i = 0u; i < n_in; ++i) {
        (void)att_node_rx(node, &in[i]);
        steps += att_node_poll(node);
        while (k < max_out && att_node_tx(node, &out[k])) {
            ++k;
        }
    }
    *n_out = k;
    return steps;
}

size_t att_host_can_quantise(const float *x, size_t n, int32_t frac_bits, int16_t *out)
{
    size_t i;
    if (x == NULL || out == NULL) {
        return 0u;
    }
    for (i = 0u; i < n; ++i) {
        out[i] = att_can_quantise(x[i], frac_bits);
    }
    return n;
}

size_t att_host_can_dequantise(const int16_t *v, size_t n, int32_t frac_bits, float *out)
{
    size_t i;
    if (v == NULL || out == NULL) {
        return 0u;
    }
    for (i = 0u; i < n; ++i) {
        out[i] = att_can_dequantise(v[i], frac_bits);
    }
    return n;
}

static att_vec3_t att_host_vec3(const float *p)
{
    att_vec3_t v;
    v.x = p[0];
    v.y = p[1];
    v.z = p[2];
    return v;
}

size_t att_host_can_encode_imu(const float *gyr, const float *acc, const float *mag, size_t n, uint32_t counter0,
                               int fd, att_can_frame_t *out)
{
    size_t i;
    att_sample_t s;
    if (gyr == NULL || acc == NULL || mag == NULL || out == NULL) {
        return 0u;
    }
    for (i = 0u; i < n; ++i) {
        uint8_t c = (uint8_t)((counter0 + (uint32_t)i) & 0x0Fu);
        s.gyr = att_host_vec3(&gyr[3u * i]);
        s.acc = att_host_vec3(&acc[3u * i]);
        s.mag = att_host_vec3(&mag[3u * i]);
        if (fd != 0) {
            att_can_encode_imu_fd(&s, c, &out[i]);
        } else {
            att_can_encode_imu(&s, c, &out[3u * i]);
        }
    }
    return (fd != 0) ? n : 3u * n;
}

size_t att_host_can_encode_outputs(const att_output_t *o, size_t n, att_filter_kind_t kind, uint32_t counter0,
                                   int fd, att_can_frame_t *out)
{
    size_t i;
    if (o == NULL || out == NULL) {
        return 0u;
    }
    for (i = 0u; i < n; ++i) {
        uint8_t c = (uint8_t)((counter0 + (uint32_t)i) & 0x0Fu);
        if (fd != 0) {
            att_can_encode_output_fd(&o[i], kind, c, &out[i]);
        } else {
            (void)att_can_encode_output_set(&o[i], kind, c, 0u, &out[6u * i]);
        }
    }
    return (fd != 0) ? n : 6u * n;
}

size_t att_host_can_check(const att_can_frame_t *f, size_t n, uint8_t *res)
{
    size_t i;
    if (f == NULL || res == NULL) {
        return 0u;
    }
    for (i = 0u; i < n; ++i) {
        res[i] = (uint8_t)att_can_check(&f[i]);
    }
    return n;
}
