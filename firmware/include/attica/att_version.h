/**
 * @file att_version.h
 * @brief The version of attica: the one place it is written.
 *
 * The C library, the CAN node and the Python package share this version: the Python package reads
 * these macros (attica.__version__, `attica --version`) and a test checks that the built extension and
 * the package metadata agree with them. Semantic versioning: MAJOR changes break the API or the CAN
 * contract, MINOR adds features, PATCH fixes.
 */
#ifndef ATT_VERSION_H
#define ATT_VERSION_H


#include "attica/att_config.h"

/* ATT_CDEF_BEGIN */
#define ATT_VERSION_MAJOR 0
#define ATT_VERSION_MINOR 1
#define ATT_VERSION_PATCH 0
/* ATT_CDEF_END */

/** The version as text, "MAJOR.MINOR.PATCH". */
#define ATT_VERSION_STRING "0.1.0"

/** The version as one comparable integer: MAJOR * 10000 + MINOR * 100 + PATCH. */
#define ATT_VERSION_NUMBER (ATT_VERSION_MAJOR * 10000 + ATT_VERSION_MINOR * 100 + ATT_VERSION_PATCH)

#endif /* ATT_VERSION_H */
