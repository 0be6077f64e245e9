/* SPDX-License-Identifier: BSD-3-Clause */
/*
 * setlight lightrig: bright regions of a lat-long HDRI extracted into area
 * lights plus a residual dome, with an energy ledger, written as USD and JSON.
 */
#ifndef SETLIGHT_LIGHTRIG_H
#define SETLIGHT_LIGHTRIG_H

#include "setlight/core.h"

#ifdef __cplusplus
extern "C" {
#endif

#ifdef __cplusplus
}
#endif

#endif /* SETLIGHT_LIGHTRIG_H */
