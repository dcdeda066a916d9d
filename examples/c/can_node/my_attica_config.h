/* my_attica_config.h: the build configuration of this node (att_config.h reads it first when the
   build defines ATT_CONFIG_HEADER="my_attica_config.h"; see the Makefile). The smallest useful node:
   the ARS filter and nothing else, no calibration stages, classic CAN frames, rings of 8 frames. */
#define ATT_WITH_MARS 0
#define ATT_WITH_KF 0
#define ATT_WITH_EKF 0
#define ATT_WITH_GYRO 0
#define ATT_WITH_TILT 0
#define ATT_WITH_MEKF 0
#define ATT_WITH_CALIB 0
#define ATT_NODE_WITH_FD 0
#define ATT_NODE_RX_RING 8
#define ATT_NODE_TX_RING 8
