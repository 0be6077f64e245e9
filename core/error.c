/* SPDX-License-Identifier: BSD-3-Clause */
#include "setlight/core.h"

#include <stdarg.h>
#include <string.h>

static const char *const result_names[SL_ERR_COUNT] = {
    [SL_OK] = "ok",
    [SL_ERR_USAGE] = "usage error",
    [SL_ERR_NOT_FOUND] = "not found",
    [SL_ERR_INPUT] = "invalid input",
    [SL_ERR_IO] = "i/o error",
    [SL_ERR_NOMEM] = "out of memory",
    [SL_ERR_UNSUPPORTED] = "unsupported",
    [SL_ERR_CANCELLED] = "cancelled",
    [SL_ERR_CAMERA] = "camera error",
    [SL_ERR_INTERNAL] = "internal error",
};

const char *sl_result_name(sl_result code)
{
    if (code < 0 || code >= SL_ERR_COUNT)
        return "unknown error";
    return result_names[code];
}

int sl_result_exit_code(sl_result code)
{
    switch (code) {
    case SL_OK:
        return 0;
    case SL_ERR_USAGE:
        return 2;
    case SL_ERR_NOT_FOUND:
    case SL_ERR_INPUT:
        return 3;
    default:
        return 1;
    }
}

sl_result sl_error_set(sl_error *err, sl_result code, const char *fmt, ...)
{
    if (err) {
        va_list ap;
        err->code = code;
        va_start(ap, fmt);
        vsnprintf(err->message, sizeof err->message, fmt, ap);
        va_end(ap);
    }
    return code;
}

void sl_error_clear(sl_error *err)
{
    if (err) {
        err->code = SL_OK;
        err->message[0] = 0;
    }
}

const char *sl_version(void)
{
#ifdef SETLIGHT_VERSION
    return SETLIGHT_VERSION;
#else
    return "0.0.0";
#endif
}
