/**
 * @file att_host_node.h
 * @brief Host-only batch helpers for the CAN codec and node (tests, tools); not part of the firmware.
 */
#ifndef ATT_HOST_NODE_H
#define ATT_HOST_NODE_H

#include "attica/att_can.h"
#include "attica/att_node.h"

/* ATT_CDEF_BEGIN */
/**
 * Feed n_in frames to the node the way a port does: for each frame att_node_rx, att_node_poll, then
 * att_node_tx into out until it is empty or out holds max_out frames. Stores the number of frames
 * written in *n_out and returns the filter steps run (the sum of att_node_poll's: sample periods, lost
 * samples integrated). NULL pointers: returns 0, *n_out untouched.
 */
size_t att_host_node_run(att_node_t *node, const att_can_frame_t *in, size_t n_in, att_can_frame_t *out,
                         size_t max_out, size_t *n_out);
/** att_can_quantise over n values. Returns n (0 for NULL). */
size_t att_host_can_quantise(const float *x, size_t n, int32_t frac_bits, int16_t *out);
/** att_can_dequantise over n values. Returns n (0 for NULL). */
size_t att_host_can_dequantise(const int16_t *v, size_t n, int32_t frac_bits, float *out);
/**
 * Encode n samples (gyr, acc, mag: n x 3 floats) with counters (counter0 + i) mod 16: fd = 0 gives 3n
 * classic frames (GYRO, ACC, MAG per sample), fd = 1 gives n IMU_FD frames. Returns the frames written.
 */
size_t att_host_can_encode_imu(const float *gyr, const float *acc, const float *mag, size_t n, uint32_t counter0,
                               int fd, att_can_frame_t *out);
/**
 * Encode n outputs as output sets (fd = 0: 6 frames each, fd = 1: one ATT_OUT_FD each), set counters
 * (counter0 + i) mod 16, error_count 0. Returns the frames written.
 */
size_t att_host_can_encode_outputs(const att_output_t *o, size_t n, att_filter_kind_t kind, uint32_t counter0,
                                   int fd, att_can_frame_t *out);
/** att_can_check over n frames into res. Returns n (0 for NULL). */
size_t att_host_can_check(const att_can_frame_t *f, size_t n, uint8_t *res);
/* ATT_CDEF_END */

#endif /* ATT_HOST_NODE_H */
