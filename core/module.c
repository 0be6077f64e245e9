/* SPDX-License-Identifier: BSD-3-Clause */
/* Modules setlight builds and loads on first use (OpenImageIO's and
 * OpenCV's shims): linked in, their libraries would cost every process
 * their loading, whether it needs them or not. */
#include "setlight/core.h"

#include <dlfcn.h>
#include <string.h>
#include <unistd.h>

void *sl_module_open(const char *built_path)
{
    const char *base = strrchr(built_path, '/');
    base = base ? base + 1 : built_path;
    char exe[4096];
    ssize_t n = readlink("/proc/self/exe", exe, sizeof exe - 1);
    char *slash = n > 0 ? (exe[n] = 0, strrchr(exe, '/')) : NULL;
    if (slash) {
        *slash = 0;
        const char *const rel[] = {"", "/.."};
        for (int i = 0; i < 2; i++) {
            char path[4400];
            snprintf(path, sizeof path, "%s%s/%s", exe, rel[i], base);
            void *h = access(path, R_OK) == 0 ? dlopen(path, RTLD_NOW | RTLD_LOCAL) : NULL;
            if (h)
                return h;
        }
    }
    return dlopen(built_path, RTLD_NOW | RTLD_LOCAL);
}
