/* SPDX-License-Identifier: BSD-3-Clause */
/* SHA-256 of the frames for the journal and the session, through OpenSSL's
 * EVP interface. */
#include <openssl/evp.h>
#include <stdio.h>
#include <string.h>

#include "setlight/capture.h"

static void to_hex(const unsigned char d[32], char hex[65])
{
    static const char digits[] = "0123456789abcdef";
    for (int i = 0; i < 32; i++) {
        hex[2 * i] = digits[d[i] >> 4];
        hex[2 * i + 1] = digits[d[i] & 15];
    }
    hex[64] = 0;
}

/* EVP fails only when it cannot allocate its context: the digest is then
 * all zeros and the hex empty, which matches no file's checksum, so a
 * verification fails rather than passes. */
void sl_sha256(const void *data, size_t size, unsigned char digest[32])
{
    unsigned int n = 0;
    if (!EVP_Digest(data, size, digest, &n, EVP_sha256(), NULL) || n != 32)
        memset(digest, 0, 32);
}

void sl_sha256_hex(const void *data, size_t size, char hex[65])
{
    unsigned char d[32];
    unsigned int n = 0;
    if (EVP_Digest(data, size, d, &n, EVP_sha256(), NULL) && n == 32)
        to_hex(d, hex);
    else
        hex[0] = 0;
}

sl_result sl_sha256_file(const char *path, char hex[65], sl_error *err)
{
    hex[0] = 0;
    FILE *f = fopen(path, "rb");
    if (!f)
        return sl_error_set(err, SL_ERR_NOT_FOUND, "%s: cannot open", path);
    EVP_MD_CTX *ctx = EVP_MD_CTX_new();
    if (!ctx || !EVP_DigestInit_ex(ctx, EVP_sha256(), NULL)) {
        EVP_MD_CTX_free(ctx);
        fclose(f);
        return sl_error_set(err, SL_ERR_NOMEM, "%s: SHA-256: out of memory", path);
    }
    unsigned char buf[65536];
    size_t n;
    bool ok = true;
    while (ok && (n = fread(buf, 1, sizeof buf, f)) > 0)
        ok = EVP_DigestUpdate(ctx, buf, n);
    bool bad = ferror(f);
    fclose(f);
    unsigned char d[32];
    unsigned int len = 0;
    ok = ok && EVP_DigestFinal_ex(ctx, d, &len) && len == 32;
    EVP_MD_CTX_free(ctx);
    if (bad)
        return sl_error_set(err, SL_ERR_IO, "%s: read failed", path);
    if (!ok)
        return sl_error_set(err, SL_ERR_INTERNAL, "%s: SHA-256 failed in OpenSSL", path);
    to_hex(d, hex);
    return SL_OK;
}
