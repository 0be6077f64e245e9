/* SPDX-License-Identifier: BSD-3-Clause */
/* A PTP/IP camera for the capture tests: enough of PTP (ISO 15740) over TCP
 * for libgphoto2's ptp2 driver to open a session, read and set exposure time,
 * f-number and ISO, trigger a capture and download the JPEG it "took".
 *
 *   ptpip_camera [--port N] [--lifetime S] [--busy N] [--busy-at K]
 *                [--ignore-shutter K] [--refuse-shutter K] [--drop-after N]
 *                [--drop-at-set K] [--scene NAME] [--qualities LIST]
 *                [--ignore-format K] [--drop-before-raw N] [--quality V]
 *
 * Prints "PORT n" on stdout once listening (port 0 or absent: picks a free one).
 * Faults: --busy N answers the next N InitiateCapture requests from capture
 * K (--busy-at, default 1) with Device Busy (0x2019); --ignore-shutter K acks
 * the K-th exposure-time change without applying it; --refuse-shutter K
 * answers the K-th exposure-time change, and every later request for that
 * value, with Invalid Device Prop Value (0x201C); --drop-after N closes
 * both connections when the trigger of frame N+1 arrives (once), then accepts
 * a new connection with the card contents kept; --drop-at-set K does the
 * same when the K-th exposure-time change arrives, before answering it (a
 * cable pulled while the camera is being set). The program exits after
 * --lifetime seconds (default 120) so a crashed test never leaves it behind.
 *
 * Image quality: CompressionSetting 0x5004 (UINT8 enumeration) with Nikon's
 * values, the vendor this camera reports so that libgphoto2's ptp2 driver
 * labels them ("imagequality": 0 JPEG Basic, 1 JPEG Normal, 2 JPEG Fine,
 * 4 NEF (Raw), 5 NEF+Basic, 6 NEF+Normal, 7 NEF+Fine; default JPEG Fine).
 * --qualities LIST offers only those values (e.g. 0,1,2: a body without
 * raw); --quality V starts at V (as set on the body before the session;
 * 3, which ptp2 cannot name, writes raw + JPEG). In a raw mode a trigger adds the raw (a linear DNG, IMG_nnnn.DNG,
 * ObjectFormat TIFF/EP) after the JPEG (or alone for NEF (Raw)): two
 * ObjectAdded events, then CaptureComplete. --ignore-format K acks the K-th
 * quality change without applying it; --drop-before-raw N closes the
 * connection when the raw of frame N is asked for (its JPEG was fetched).
 *
 * The photographs: a horizontal ramp of radiance spanning 22 stops, exposed
 * with the set exposure time, f-number and ISO (linear, then sRGB-encoded),
 * so pixel ratios between two frames follow their exposure ratio. EXIF holds
 * the exposure actually used. With --scene NAME (a virtual-set preset or
 * scene file) they are the virtual camera's photographs of that scene at the
 * nearest speed, aperture and ISO that body offers, with its EXIF. */
#include <arpa/inet.h>
#include <errno.h>
#include <math.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <poll.h>
#include <signal.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <time.h>
#include <unistd.h>

#include "setlight/vset.h"

enum {
    PKT_INIT_CMD_REQ = 1,
    PKT_INIT_CMD_ACK = 2,
    PKT_INIT_EVT_REQ = 3,
    PKT_INIT_EVT_ACK = 4,
    PKT_CMD_REQ = 6,
    PKT_CMD_RESP = 7,
    PKT_EVENT = 8,
    PKT_START_DATA = 9,
    PKT_DATA = 10,
    PKT_END_DATA = 12,
    PKT_PING = 13,
    PKT_PONG = 14
};
enum {
    OC_GetDeviceInfo = 0x1001,
    OC_OpenSession = 0x1002,
    OC_CloseSession = 0x1003,
    OC_GetStorageIDs = 0x1004,
    OC_GetStorageInfo = 0x1005,
    OC_GetNumObjects = 0x1006,
    OC_GetObjectHandles = 0x1007,
    OC_GetObjectInfo = 0x1008,
    OC_GetObject = 0x1009,
    OC_InitiateCapture = 0x100E,
    OC_GetDevicePropDesc = 0x1014,
    OC_GetDevicePropValue = 0x1015,
    OC_SetDevicePropValue = 0x1016
};
enum {
    RC_OK = 0x2001,
    RC_GeneralError = 0x2002,
    RC_SessionNotOpen = 0x2003,
    RC_OperationNotSupported = 0x2005,
    RC_InvalidStorageID = 0x2008,
    RC_InvalidObjectHandle = 0x2009,
    RC_DevicePropNotSupported = 0x200A,
    RC_DeviceBusy = 0x2019,
    RC_InvalidDevicePropValue = 0x201C,
    RC_SessionAlreadyOpen = 0x201E
};
enum { EC_ObjectAdded = 0x4002, EC_CaptureComplete = 0x400D };
enum {
    DPC_CompressionSetting = 0x5004,
    DPC_FNumber = 0x5007,
    DPC_ExposureTime = 0x500D,
    DPC_ExposureIndex = 0x500F
};
enum { OFC_JPEG = 0x3801, OFC_TIFF_EP = 0x3802 };
#define VENDOR_NIKON 0x0000000Au
#define STORAGE_ID 0x00010001u

static const uint16_t k_ops[] = {OC_GetDeviceInfo,     OC_OpenSession,       OC_CloseSession,
                                 OC_GetStorageIDs,     OC_GetStorageInfo,    OC_GetNumObjects,
                                 OC_GetObjectHandles,  OC_GetObjectInfo,     OC_GetObject,
                                 OC_InitiateCapture,   OC_GetDevicePropDesc, OC_GetDevicePropValue,
                                 OC_SetDevicePropValue};
static const uint16_t k_events[] = {EC_ObjectAdded, EC_CaptureComplete};
static const uint16_t k_props[] = {DPC_CompressionSetting, DPC_FNumber, DPC_ExposureTime,
                                   DPC_ExposureIndex};

/* Offered values: exposure time in 1/10000 s (third stops from 1/10000 s to
 * 30 s, as PTP's unit allows), f-number in 1/100, ISO. */
static uint32_t g_shutters[64];
static int g_shutter_count;
static const uint16_t k_fnumbers[] = {280, 400, 560, 800, 1100, 1600};
static const uint16_t k_isos[] = {100, 200, 400, 800, 1600};
/* CompressionSetting values offered (--qualities), Nikon's numbering. */
static uint8_t g_qualities[8] = {0, 1, 2, 4, 5, 6, 7};
static int g_quality_count = 7;
#define QUALITY_RAW 4 /* 4: raw alone, 5..7: raw + JPEG */

typedef struct {
    uint8_t *data;
    size_t size, cap;
} buf;

static void put(buf *b, const void *p, size_t n)
{
    if (b->size + n > b->cap) {
        b->cap = (b->size + n) * 2 + 64;
        b->data = realloc(b->data, b->cap);
        if (!b->data)
            abort();
    }
    memcpy(b->data + b->size, p, n);
    b->size += n;
}
static void put8(buf *b, uint8_t v)
{
    put(b, &v, 1);
}
static void put16(buf *b, uint16_t v)
{
    uint8_t x[2] = {(uint8_t)v, (uint8_t)(v >> 8)};
    put(b, x, 2);
}
static void put32(buf *b, uint32_t v)
{
    uint8_t x[4] = {(uint8_t)v, (uint8_t)(v >> 8), (uint8_t)(v >> 16), (uint8_t)(v >> 24)};
    put(b, x, 4);
}
static void put64(buf *b, uint64_t v)
{
    put32(b, (uint32_t)v);
    put32(b, (uint32_t)(v >> 32));
}
/* PTP string: count of UCS-2 units including the terminator, then the units. */
static void putstr(buf *b, const char *s)
{
    size_t n = strlen(s);
    if (n == 0) {
        put8(b, 0);
        return;
    }
    put8(b, (uint8_t)(n + 1));
    for (size_t i = 0; i <= n; i++)
        put16(b, (uint8_t)s[i]);
}
static void put16array(buf *b, const uint16_t *v, int n)
{
    put32(b, (uint32_t)n);
    for (int i = 0; i < n; i++)
        put16(b, v[i]);
}
static uint32_t get32(const uint8_t *p)
{
    return p[0] | p[1] << 8 | p[2] << 16 | (uint32_t)p[3] << 24;
}
static uint16_t get16(const uint8_t *p)
{
    return (uint16_t)(p[0] | p[1] << 8);
}

typedef struct {
    uint32_t handle;
    char name[32];
    uint16_t format; /* ObjectFormat */
    int frame;       /* the trigger that made it, from 1 */
    uint8_t *data;
    size_t size;
    char date[32]; /* PTP "YYYYMMDDThhmmss" */
} object;

static struct {
    int busy_left, busy_at, ignore_shutter, refuse_shutter, drop_after, drop_at_set, shutter_requests;
    uint32_t refused; /* the exposure-time value refused since --refuse-shutter */
    sl_camera *scene; /* --scene: the virtual camera that takes the pictures */
    bool dropped;
    uint32_t shutter, fnumber, iso, quality;
    int shutter_sets;
    int ignore_format, format_sets, drop_before_raw;
    bool dropped_raw;
    int captures; /* frames taken */
    object objects[1024];
    int object_count;
    int cmd_fd, evt_fd;
    bool session_open;
} g;

static int write_all(int fd, const void *p, size_t n)
{
    const uint8_t *c = p;
    while (n > 0) {
        ssize_t w = send(fd, c, n, MSG_NOSIGNAL);
        if (w < 0 && errno == EINTR)
            continue;
        if (w <= 0)
            return -1;
        c += w;
        n -= (size_t)w;
    }
    return 0;
}
static int read_all(int fd, void *p, size_t n)
{
    uint8_t *c = p;
    while (n > 0) {
        ssize_t r = recv(fd, c, n, 0);
        if (r < 0 && errno == EINTR)
            continue;
        if (r <= 0)
            return -1;
        c += r;
        n -= (size_t)r;
    }
    return 0;
}

/* Reads one packet; *payload is malloc'd (may be empty). */
static bool g_debug;

static int read_packet(int fd, uint32_t *type, uint8_t **payload, uint32_t *len)
{
    uint8_t hdr[8];
    *payload = NULL;
    if (read_all(fd, hdr, 8)) {
        if (g_debug)
            fprintf(stderr, "ptpip_camera: fd %d closed\n", fd);
        return -1;
    }
    uint32_t total = get32(hdr);
    *type = get32(hdr + 4);
    if (total < 8 || total > (64u << 20))
        return -1;
    *len = total - 8;
    if (g_debug)
        fprintf(stderr, "ptpip_camera: fd %d packet type %u length %u%s\n", fd, *type, total,
                *type == PKT_CMD_REQ ? " (operation follows)" : "");
    *payload = malloc(*len + 1);
    if (!*payload || read_all(fd, *payload, *len)) {
        free(*payload);
        *payload = NULL;
        return -1;
    }
    return 0;
}

static int send_packet(int fd, uint32_t type, const void *payload, size_t n)
{
    buf b = {0};
    put32(&b, (uint32_t)(n + 8));
    put32(&b, type);
    if (n)
        put(&b, payload, n);
    int r = write_all(fd, b.data, b.size);
    free(b.data);
    return r;
}

static int send_response(uint16_t code, uint32_t tid, const uint32_t *params, int n)
{
    buf b = {0};
    put16(&b, code);
    put32(&b, tid);
    for (int i = 0; i < n; i++)
        put32(&b, params[i]);
    int r = send_packet(g.cmd_fd, PKT_CMD_RESP, b.data, b.size);
    free(b.data);
    return r;
}

static int send_event(uint16_t code, uint32_t tid, uint32_t param)
{
    buf b = {0};
    put16(&b, code);
    put32(&b, tid);
    put32(&b, param);
    int r = send_packet(g.evt_fd, PKT_EVENT, b.data, b.size);
    free(b.data);
    return r;
}

/* Data phase to the host: start data, then data packets, the last one "end". */
static int send_data(uint32_t tid, const uint8_t *data, size_t n)
{
    buf b = {0};
    put32(&b, tid);
    put64(&b, n);
    int r = send_packet(g.cmd_fd, PKT_START_DATA, b.data, b.size);
    free(b.data);
    size_t off = 0;
    do {
        size_t chunk = n - off > 65536 ? 65536 : n - off;
        buf p = {0};
        put32(&p, tid);
        if (chunk)
            put(&p, data + off, chunk);
        off += chunk;
        if (!r)
            r = send_packet(g.cmd_fd, off == n ? PKT_END_DATA : PKT_DATA, p.data, p.size);
        free(p.data);
    } while (off < n && !r);
    return r;
}

/* Data phase from the host: start data, data..., end data. */
static int recv_data(buf *out)
{
    for (;;) {
        uint32_t type, len;
        uint8_t *p;
        if (read_packet(g.cmd_fd, &type, &p, &len))
            return -1;
        if (type == PKT_START_DATA) {
            free(p);
            continue;
        }
        if ((type == PKT_DATA || type == PKT_END_DATA) && len >= 4)
            put(out, p + 4, len - 4);
        free(p);
        if (type == PKT_END_DATA)
            return 0;
        if (type != PKT_DATA)
            return -1;
    }
}

static void device_info(buf *b)
{
    put16(b, 100); /* standard version 1.00 */
    /* Nikon's extension ID, so that ptp2 labels CompressionSetting as a
     * Nikon body's menu does; no Nikon operation is offered, so the driver
     * keeps to the plain PTP property set and InitiateCapture. */
    put32(b, VENDOR_NIKON);
    put16(b, 100);
    putstr(b, "");
    put16(b, 0); /* functional mode */
    put16array(b, k_ops, (int)(sizeof k_ops / sizeof k_ops[0]));
    put16array(b, k_events, 2);
    put16array(b, k_props, 4);
    const uint16_t formats[2] = {OFC_JPEG, OFC_TIFF_EP};
    put16array(b, formats, 2); /* capture formats */
    put16array(b, formats, 2); /* image formats */
    putstr(b, "setlight");
    putstr(b, "PTP-IP test camera");
    putstr(b, "1.0");
    putstr(b, "SL0001");
}

static void prop_value(buf *b, uint16_t prop)
{
    if (prop == DPC_CompressionSetting)
        put8(b, (uint8_t)g.quality);
    else if (prop == DPC_ExposureTime)
        put32(b, g.shutter);
    else if (prop == DPC_FNumber)
        put16(b, (uint16_t)g.fnumber);
    else
        put16(b, (uint16_t)g.iso);
}

static void prop_desc(buf *b, uint16_t prop)
{
    put16(b, prop);
    bool u32 = prop == DPC_ExposureTime, u8 = prop == DPC_CompressionSetting;
    put16(b, u32 ? 0x0006 : u8 ? 0x0002 : 0x0004); /* UINT32 / UINT8 / UINT16 */
    put8(b, 1);                      /* get/set */
    prop_value(b, prop);             /* factory default: whatever is current */
    prop_value(b, prop);
    put8(b, 2); /* enumeration form */
    if (prop == DPC_CompressionSetting) {
        put16(b, (uint16_t)g_quality_count);
        for (int i = 0; i < g_quality_count; i++)
            put8(b, g_qualities[i]);
    } else if (prop == DPC_ExposureTime) {
        put16(b, (uint16_t)g_shutter_count);
        for (int i = 0; i < g_shutter_count; i++)
            put32(b, g_shutters[i]);
    } else if (prop == DPC_FNumber) {
        put16(b, 6);
        for (int i = 0; i < 6; i++)
            put16(b, k_fnumbers[i]);
    } else {
        put16(b, 5);
        for (int i = 0; i < 5; i++)
            put16(b, k_isos[i]);
    }
}

static bool offered(uint16_t prop, uint32_t v)
{
    if (prop == DPC_CompressionSetting) {
        for (int i = 0; i < g_quality_count; i++)
            if (g_qualities[i] == v)
                return true;
    } else if (prop == DPC_ExposureTime) {
        for (int i = 0; i < g_shutter_count; i++)
            if (g_shutters[i] == v)
                return true;
    } else if (prop == DPC_FNumber) {
        for (int i = 0; i < 6; i++)
            if (k_fnumbers[i] == v)
                return true;
    } else {
        for (int i = 0; i < 5; i++)
            if (k_isos[i] == v)
                return true;
    }
    return false;
}

static bool is_prop(uint32_t prop)
{
    for (size_t i = 0; i < sizeof k_props / sizeof k_props[0]; i++)
        if (k_props[i] == prop)
            return true;
    return false;
}

static object *find_object(uint32_t h)
{
    for (int i = 0; i < g.object_count; i++)
        if (g.objects[i].handle == h)
            return &g.objects[i];
    return NULL;
}

/* Adds one file of the trigger being taken (frame g.captures + 1) to the
 * card: IMG_nnnn.EXT, its JPEG and raw sharing the number. Takes `data`. */
static bool add_object(const char *ext, uint16_t format, uint8_t *data, size_t size)
{
    if (!data || g.object_count == (int)(sizeof g.objects / sizeof g.objects[0])) {
        free(data);
        return false;
    }
    object *o = &g.objects[g.object_count];
    memset(o, 0, sizeof *o);
    o->handle = 0x1000u + (uint32_t)g.object_count;
    o->frame = g.captures + 1;
    o->format = format;
    o->data = data;
    o->size = size;
    snprintf(o->name, sizeof o->name, "IMG_%04d.%s", o->frame, ext);
    /* A fixed clock, one second per frame, so runs are reproducible. */
    time_t when = 1767268800 + o->frame - 1; /* 2026-01-01 12:00:00 UTC */
    struct tm tm;
    gmtime_r(&when, &tm);
    strftime(o->date, sizeof o->date, "%Y%m%dT%H%M%S", &tm);
    g.object_count++;
    return true;
}

/* 3 is no Nikon value (ptp2 shows "Unknown value 0003"): here a raw+JPEG
 * mode whose label nobody can read. */
static bool quality_raw(void)
{
    return g.quality >= QUALITY_RAW || g.quality == 3;
}
static bool quality_jpeg(void)
{
    return g.quality != QUALITY_RAW;
}

/* The virtual camera's photographs, in the format the quality asks for. */
static bool scene_picture(double t, double n, double iso)
{
    sl_camera_settings s = {t, n, iso};
    sl_image_format format = !quality_raw()   ? SL_FORMAT_JPEG
                             : quality_jpeg() ? SL_FORMAT_RAW_JPEG
                                              : SL_FORMAT_RAW;
    sl_camera_shot f;
    sl_error err;
    if (sl_camera_set_format(g.scene, format, NULL, &err) || sl_camera_set(g.scene, &s, &err) ||
        sl_camera_capture(g.scene, &f, &err)) {
        fprintf(stderr, "ptpip_camera: %s\n", err.message);
        return false;
    }
    bool ok = true;
    for (int i = 0; i < f.count && ok; i++) {
        bool raw = sl_image_format_of_file(f.files[i].source) == SL_FORMAT_RAW;
        ok = add_object(raw ? "DNG" : "JPG", raw ? OFC_TIFF_EP : OFC_JPEG, f.files[i].data,
                        f.files[i].size);
        f.files[i].data = NULL;
    }
    sl_camera_shot_free(&f);
    return ok;
}

/* An sRGB-encoded JPEG with EXIF, through sl_photo_write (which wants a
 * path: a private folder, removed right after). */
static uint8_t *jpeg_bytes(const sl_image *srgb, const sl_meta *meta, size_t *size)
{
    char dir[64] = "/tmp/ptpip_camera.XXXXXX", path[128];
    sl_error err;
    sl_result r = mkdtemp(dir) ? SL_OK : sl_error_set(&err, SL_ERR_IO, "%s: mkdtemp", dir);
    snprintf(path, sizeof path, "%s/frame.jpg", dir);
    if (!r)
        r = sl_photo_write(path, srgb, meta, 8, &err);
    FILE *f = r ? NULL : fopen(path, "rb");
    uint8_t *data = NULL;
    if (f) {
        fseek(f, 0, SEEK_END);
        long n = ftell(f);
        fseek(f, 0, SEEK_SET);
        data = n > 0 ? malloc((size_t)n) : NULL;
        if (data && fread(data, 1, (size_t)n, f) != (size_t)n) {
            free(data);
            data = NULL;
        }
        *size = data ? (size_t)n : 0;
        fclose(f);
    } else
        fprintf(stderr, "ptpip_camera: %s\n", r ? err.message : path);
    remove(path);
    rmdir(dir);
    return data;
}

/* Takes a picture with the current settings: its JPEG and/or raw go on
 * the card. False when that failed. */
static bool take_picture(void)
{
    const int w = 256, h = 64;
    double t = g.shutter / 10000.0, n = g.fnumber / 100.0, iso = g.iso;
    bool ok;
    if (g.scene)
        ok = scene_picture(t, n, iso);
    else {
        /* Exposure scale: a radiance of 1 at 1/30 s, f/4, ISO 100 gives 0.18. */
        double k = 0.18 * 30.0 * 16.0 * t * iso / 100.0 / (n * n);
        sl_image lin, srgb;
        sl_error err;
        if (sl_image_alloc(&lin, w, h, 3, &err))
            return false;
        if (sl_image_alloc(&srgb, w, h, 3, &err)) {
            sl_image_free(&lin);
            return false;
        }
        for (int y = 0; y < h; y++)
            for (int x = 0; x < w; x++) {
                double stops = -11.0 + 22.0 * (x + 0.5) / w;
                double radiance = exp2(stops) * (1.0 + 0.1 * sin(0.3 * y));
                float *p = sl_image_pixel(&lin, x, y), *q = sl_image_pixel(&srgb, x, y);
                for (int c = 0; c < 3; c++) {
                    double v = radiance * k * (c == 0 ? 1.0 : c == 1 ? 0.9 : 0.8);
                    p[c] = (float)(v > 1.0 ? 1.0 : v);
                    q[c] = sl_linear_to_srgb(p[c]);
                }
            }
        time_t when = 1767268800 + g.captures;
        struct tm tm;
        gmtime_r(&when, &tm);
        sl_meta meta;
        sl_meta_init(&meta);
        meta.exposure_time = t;
        meta.f_number = n;
        meta.iso = iso;
        meta.focal_length_mm = 8.0;
        snprintf(meta.make, sizeof meta.make, "setlight");
        snprintf(meta.model, sizeof meta.model, "PTP-IP test camera");
        strftime(meta.datetime, sizeof meta.datetime, "%Y:%m:%d %H:%M:%S", &tm);
        size_t size = 0;
        ok = true;
        if (quality_jpeg()) {
            uint8_t *jpeg = jpeg_bytes(&srgb, &meta, &size);
            ok = add_object("JPG", OFC_JPEG, jpeg, size);
        }
        unsigned char *dng = NULL;
        if (ok && quality_raw())
            ok = !sl_dng_encode(&lin, &meta, 0, &dng, &size, &err) &&
                 add_object("DNG", OFC_TIFF_EP, dng, size);
        sl_meta_free(&meta);
        sl_image_free(&lin);
        sl_image_free(&srgb);
    }
    if (ok)
        g.captures++;
    return ok;
}

static void object_info(buf *b, const object *o)
{
    put32(b, STORAGE_ID);
    put16(b, o->format);
    put16(b, 0);
    put32(b, (uint32_t)o->size);
    put16(b, 0);
    put32(b, 0);
    put32(b, 0);
    put32(b, 0);
    put32(b, 256);
    put32(b, 64);
    put32(b, 24);
    put32(b, 0); /* parent: root */
    put16(b, 0);
    put32(b, 0);
    put32(b, o->handle - 0x1000u + 1); /* sequence number */
    putstr(b, o->name);
    putstr(b, o->date);
    putstr(b, o->date);
    putstr(b, "");
}

/* Handles one operation; returns -1 when the connection is to be dropped. */
static int operation(uint16_t code, uint32_t tid, const uint32_t *p, int np)
{
    buf d = {0};
    int r = 0;
    if (code != OC_GetDeviceInfo && code != OC_OpenSession && !g.session_open)
        return send_response(RC_SessionNotOpen, tid, NULL, 0);
    switch (code) {
    case OC_GetDeviceInfo:
        device_info(&d);
        r = send_data(tid, d.data, d.size);
        if (!r)
            r = send_response(RC_OK, tid, NULL, 0);
        break;
    case OC_OpenSession:
        if (g.session_open) {
            r = send_response(RC_SessionAlreadyOpen, tid, NULL, 0);
            break;
        }
        g.session_open = true;
        r = send_response(RC_OK, tid, NULL, 0);
        break;
    case OC_CloseSession:
        g.session_open = false;
        r = send_response(RC_OK, tid, NULL, 0);
        break;
    case OC_GetStorageIDs: {
        put32(&d, 1);
        put32(&d, STORAGE_ID);
        r = send_data(tid, d.data, d.size);
        if (!r)
            r = send_response(RC_OK, tid, NULL, 0);
        break;
    }
    case OC_GetStorageInfo:
        if (np < 1 || p[0] != STORAGE_ID) {
            r = send_response(RC_InvalidStorageID, tid, NULL, 0);
            break;
        }
        put16(&d, 0x0004); /* removable RAM */
        put16(&d, 0x0002); /* generic hierarchical */
        put16(&d, 0x0000); /* read-write */
        put64(&d, 32ull << 30);
        put64(&d, 16ull << 30);
        put32(&d, 100000);
        putstr(&d, "SD card");
        putstr(&d, "SETLIGHT");
        r = send_data(tid, d.data, d.size);
        if (!r)
            r = send_response(RC_OK, tid, NULL, 0);
        break;
    case OC_GetNumObjects:
    case OC_GetObjectHandles: {
        /* Everything lives in the root folder of the one card. */
        bool root = np < 3 || p[2] == 0 || p[2] == 0xFFFFFFFFu;
        bool store = np < 1 || p[0] == STORAGE_ID || p[0] == 0xFFFFFFFFu;
        int n = root && store ? g.object_count : 0;
        if (code == OC_GetNumObjects) {
            uint32_t v = (uint32_t)n;
            r = send_response(RC_OK, tid, &v, 1);
            break;
        }
        put32(&d, (uint32_t)n);
        for (int i = 0; i < n; i++)
            put32(&d, g.objects[i].handle);
        r = send_data(tid, d.data, d.size);
        if (!r)
            r = send_response(RC_OK, tid, NULL, 0);
        break;
    }
    case OC_GetObjectInfo:
    case OC_GetObject: {
        object *o = np >= 1 ? find_object(p[0]) : NULL;
        if (!o) {
            r = send_response(RC_InvalidObjectHandle, tid, NULL, 0);
            break;
        }
        if (code == OC_GetObjectInfo) {
            object_info(&d, o);
            r = send_data(tid, d.data, d.size);
        } else if (code == OC_GetObject && o->format == OFC_TIFF_EP &&
                   o->frame == g.drop_before_raw && !g.dropped_raw) {
            g.dropped_raw = true;
            fprintf(stderr, "ptpip_camera: dropping the connection before the raw of frame %d\n",
                    o->frame);
            return -1;
        } else
            r = send_data(tid, o->data, o->size);
        if (!r)
            r = send_response(RC_OK, tid, NULL, 0);
        break;
    }
    case OC_GetDevicePropDesc:
    case OC_GetDevicePropValue:
        if (np < 1 || !is_prop(p[0])) {
            r = send_response(RC_DevicePropNotSupported, tid, NULL, 0);
            break;
        }
        if (code == OC_GetDevicePropDesc)
            prop_desc(&d, (uint16_t)p[0]);
        else
            prop_value(&d, (uint16_t)p[0]);
        r = send_data(tid, d.data, d.size);
        if (!r)
            r = send_response(RC_OK, tid, NULL, 0);
        break;
    case OC_SetDevicePropValue: {
        if (recv_data(&d))
            return -1;
        uint16_t prop = np >= 1 ? (uint16_t)p[0] : 0;
        uint32_t v = d.size >= 4   ? get32(d.data)
                     : d.size >= 2 ? get16(d.data)
                     : d.size >= 1 ? d.data[0]
                                   : 0;
        if (!is_prop(prop)) {
            r = send_response(RC_DevicePropNotSupported, tid, NULL, 0);
            break;
        }
        if (!offered(prop, v)) {
            r = send_response(RC_InvalidDevicePropValue, tid, NULL, 0);
            break;
        }
        if (prop == DPC_ExposureTime && ++g.shutter_requests == g.drop_at_set) {
            fprintf(stderr, "ptpip_camera: dropping the connection at exposure-time change %d\n",
                    g.shutter_requests);
            free(d.data);
            return -1;
        }
        if (prop == DPC_ExposureTime &&
            ((g.refused && v == g.refused) || g.shutter_sets + 1 == g.refuse_shutter)) {
            g.shutter_sets += v != g.refused;
            g.refused = v;
            fprintf(stderr, "ptpip_camera: refusing exposure time %u\n", (unsigned)v);
            r = send_response(RC_InvalidDevicePropValue, tid, NULL, 0);
            break;
        }
        if (prop == DPC_CompressionSetting) {
            if (v != g.quality && ++g.format_sets == g.ignore_format)
                fprintf(stderr, "ptpip_camera: ignoring image quality change %d\n", g.format_sets);
            else
                g.quality = v;
        } else if (prop == DPC_ExposureTime) {
            g.shutter_sets++;
            if (g.shutter_sets != g.ignore_shutter)
                g.shutter = v;
            else
                fprintf(stderr, "ptpip_camera: ignoring shutter change %d\n", g.shutter_sets);
        } else if (prop == DPC_FNumber)
            g.fnumber = v;
        else
            g.iso = v;
        r = send_response(RC_OK, tid, NULL, 0);
        break;
    }
    case OC_InitiateCapture: {
        if (g.drop_after > 0 && !g.dropped && g.captures == g.drop_after) {
            g.dropped = true;
            fprintf(stderr, "ptpip_camera: dropping the connection after frame %d\n", g.captures);
            free(d.data);
            return -1;
        }
        if (g.busy_left > 0 && g.captures + 1 >= g.busy_at) {
            g.busy_left--;
            fprintf(stderr, "ptpip_camera: busy reply to the trigger of frame %d\n",
                    g.captures + 1);
            r = send_response(RC_DeviceBusy, tid, NULL, 0);
            break;
        }
        int first = g.object_count;
        if (!take_picture()) {
            r = send_response(RC_GeneralError, tid, NULL, 0);
            break;
        }
        r = send_response(RC_OK, tid, NULL, 0);
        for (int i = first; i < g.object_count && !r; i++)
            r = send_event(EC_ObjectAdded, tid, g.objects[i].handle);
        if (!r)
            r = send_event(EC_CaptureComplete, tid, 0);
        break;
    }
    default:
        r = send_response(RC_OperationNotSupported, tid, NULL, 0);
    }
    free(d.data);
    return r;
}

static int accept_timeout(int lfd, int ms)
{
    struct pollfd pfd = {lfd, POLLIN, 0};
    int n = poll(&pfd, 1, ms);
    if (n <= 0)
        return -1;
    int fd = accept(lfd, NULL, NULL);
    if (fd >= 0) {
        int one = 1;
        setsockopt(fd, IPPROTO_TCP, TCP_NODELAY, &one, sizeof one);
    }
    return fd;
}

/* One host connection: the command channel, then the event channel. */
static int send_cmd_ack(int fd)
{
    buf b = {0};
    put32(&b, 1); /* connection number */
    const uint8_t guid[16] = {0x53, 0x4c, 0x50, 0x54, 0x50, 0x49, 0x50, 1};
    put(&b, guid, 16);
    const char *name = "setlight-cam";
    for (size_t i = 0; i <= strlen(name); i++)
        put16(&b, (uint8_t)name[i]);
    put32(&b, 0x00010000);
    int r = send_packet(fd, PKT_INIT_CMD_ACK, b.data, b.size);
    free(b.data);
    return r;
}

/* One host connection: a command channel, then its event channel. Any new
 * connection that opens with an init command request starts over, so a host
 * that gave up half-way never leaves the camera waiting for the wrong socket. */
static void serve(int lfd)
{
    uint32_t type, len;
    uint8_t *p;
    g.cmd_fd = g.evt_fd = -1;
    g.session_open = false;
    while (g.evt_fd < 0) {
        int fd = accept_timeout(lfd, 5000);
        if (fd < 0)
            goto out;
        if (read_packet(fd, &type, &p, &len)) {
            close(fd);
            continue;
        }
        free(p);
        if (type == PKT_INIT_CMD_REQ && !send_cmd_ack(fd)) {
            if (g.cmd_fd >= 0)
                close(g.cmd_fd);
            g.cmd_fd = fd;
        } else if (type == PKT_INIT_EVT_REQ && g.cmd_fd >= 0 &&
                   !send_packet(fd, PKT_INIT_EVT_ACK, NULL, 0))
            g.evt_fd = fd;
        else
            close(fd);
    }
    for (;;) {
        struct pollfd pfd[2] = {{g.cmd_fd, POLLIN, 0}, {g.evt_fd, POLLIN, 0}};
        if (poll(pfd, 2, 1000) < 0 && errno != EINTR)
            break;
        if (pfd[1].revents) {
            /* The host only pings on the event channel, or closes it. */
            if (read_packet(g.evt_fd, &type, &p, &len))
                break;
            free(p);
            if (type == PKT_PING && send_packet(g.evt_fd, PKT_PONG, NULL, 0))
                break;
        }
        if (!pfd[0].revents)
            continue;
        if (read_packet(g.cmd_fd, &type, &p, &len))
            break;
        if (type == PKT_PING) {
            free(p);
            if (send_packet(g.cmd_fd, PKT_PONG, NULL, 0))
                break;
            continue;
        }
        if (type != PKT_CMD_REQ || len < 10) {
            free(p);
            break;
        }
        uint16_t code = get16(p + 4);
        uint32_t tid = get32(p + 6);
        if (g_debug)
            fprintf(stderr, "ptpip_camera: operation 0x%04x transaction %u\n", code, tid);
        uint32_t params[5] = {0};
        int np = (int)((len - 10) / 4);
        if (np > 5)
            np = 5;
        for (int i = 0; i < np; i++)
            params[i] = get32(p + 10 + 4 * i);
        free(p);
        if (operation(code, tid, params, np))
            break;
    }
out:
    if (g.evt_fd >= 0)
        close(g.evt_fd);
    if (g.cmd_fd >= 0)
        close(g.cmd_fd);
    g.evt_fd = g.cmd_fd = -1;
}

int main(int argc, char **argv)
{
    int port = 0, start_quality = 2; /* JPEG Fine */
    double lifetime = 120;
    g.busy_at = 1;
    for (int i = 1; i < argc; i++) {
        const char *a = argv[i], *v = i + 1 < argc ? argv[i + 1] : NULL;
        if (!v) {
            fprintf(stderr, "ptpip_camera: %s needs a value\n", a);
            return 2;
        }
        if (!strcmp(a, "--port"))
            port = atoi(v);
        else if (!strcmp(a, "--lifetime"))
            lifetime = atof(v);
        else if (!strcmp(a, "--busy"))
            g.busy_left = atoi(v);
        else if (!strcmp(a, "--busy-at"))
            g.busy_at = atoi(v);
        else if (!strcmp(a, "--ignore-shutter"))
            g.ignore_shutter = atoi(v);
        else if (!strcmp(a, "--scene")) {
            char port[600];
            snprintf(port, sizeof port, "virtual:%s", v ? v : "");
            sl_error err;
            if (sl_vset_camera_register(&err) || sl_camera_open(port, &g.scene, &err)) {
                fprintf(stderr, "ptpip_camera: %s\n", err.message);
                return 2;
            }
        } else if (!strcmp(a, "--refuse-shutter"))
            g.refuse_shutter = atoi(v);
        else if (!strcmp(a, "--drop-after"))
            g.drop_after = atoi(v);
        else if (!strcmp(a, "--drop-at-set"))
            g.drop_at_set = atoi(v);
        else if (!strcmp(a, "--ignore-format"))
            g.ignore_format = atoi(v);
        else if (!strcmp(a, "--drop-before-raw"))
            g.drop_before_raw = atoi(v);
        else if (!strcmp(a, "--quality"))
            start_quality = atoi(v);
        else if (!strcmp(a, "--qualities")) {
            g_quality_count = 0;
            for (const char *c = v; *c && g_quality_count < 8; c += strcspn(c, ","), c += !!*c)
                g_qualities[g_quality_count++] = (uint8_t)atoi(c);
        } else {
            fprintf(stderr, "ptpip_camera: unknown option %s\n", a);
            return 2;
        }
        i++;
    }
    for (int k = 0; k <= 55 && g_shutter_count < 64; k++) {
        uint32_t u = (uint32_t)lround(exp2(k / 3.0)); /* 1 .. 327680 (1/10000 s .. 33 s) */
        if (g_shutter_count == 0 || g_shutters[g_shutter_count - 1] != u)
            g_shutters[g_shutter_count++] = u;
    }
    g.shutter = g_shutters[0];
    for (int i = 0; i < g_shutter_count; i++)
        if (g_shutters[i] <= 333)
            g.shutter = g_shutters[i];
    g.fnumber = 400;
    g.iso = 100;
    g.quality = g_qualities[0];
    for (int i = 0; i < g_quality_count; i++)
        if (g_qualities[i] == start_quality)
            g.quality = (uint32_t)start_quality;
    g_debug = getenv("PTPIP_CAMERA_DEBUG") != NULL;
    signal(SIGPIPE, SIG_IGN);
    int lfd = socket(AF_INET, SOCK_STREAM, 0);
    int one = 1;
    setsockopt(lfd, SOL_SOCKET, SO_REUSEADDR, &one, sizeof one);
    struct sockaddr_in a = {0};
    a.sin_family = AF_INET;
    a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    a.sin_port = htons((uint16_t)port);
    socklen_t alen = sizeof a;
    if (bind(lfd, (struct sockaddr *)&a, sizeof a) || listen(lfd, 4) ||
        getsockname(lfd, (struct sockaddr *)&a, &alen)) {
        fprintf(stderr, "ptpip_camera: cannot listen on port %d: %s\n", port, strerror(errno));
        return 1;
    }
    printf("PORT %d\n", ntohs(a.sin_port));
    fflush(stdout);
    /* The default action of SIGALRM ends the process wherever it is. */
    alarm((unsigned)ceil(lifetime));
    for (;;)
        serve(lfd);
}
