/* SPDX-License-Identifier: BSD-3-Clause */
/* Camera and photo formats through OpenImageIO 2.4, behind the C API in
 * core.h (under photo_private.h's sl_oiio_* names: core/photo.c reads PNG
 * itself). No exception crosses into C.
 *
 * Reading returns subimage 0, mip level 0, the data window, the first (up to)
 * four channels, as float: integer formats scaled to [0, 1] with no transfer
 * function removed, alpha left unassociated as stored. No orientation is
 * applied: the EXIF Orientation is reported in meta->orientation for the
 * caller to honour. meta->colorspace is OIIO's "oiio:ColorSpace" verbatim
 * (e.g. "sRGB", "Linear"); sl_color_space_name() maps aliases to the config.
 *
 * Camera raw (and DNG) goes through OIIO's LibRaw plugin, configured for
 * scene-linear data: raw:ColorSpace "sRGB-linear" (Rec.709 primaries, no
 * tone curve), raw:use_camera_wb 1 (as-shot white balance), raw:auto_bright 0
 * (no exposure guess, so brackets keep their ratios), raw:HighlightMode 0
 * (clip: saturated photosites stay at the white level, where a merge can
 * discard them), raw:user_flip 0 (pixels in sensor
 * order, like every other format here), raw:Demosaic "AHD" (LibRaw's default,
 * said explicitly). raw:apply_scene_linear_scale is never set: OpenImageIO
 * 2.4 scales by 2.22 and returns float whenever the attribute is present,
 * even at 0; without it values stay relative to the white level (1.0 =
 * sensor saturation; test_capture_format reads a DNG's white at 1.0).
 *
 * Writing: what survives is what OIIO 2.4 writes per format. JPEG keeps all
 * the EXIF fields; TIFF all but ISO; PNG only the text ones (make, model,
 * lens, date) plus setlight:* attributes as text chunks. */
#include "setlight/core.h"
#include "exr_oiio.h"

#include <ImfChannelList.h>
#include <ImfFrameBuffer.h>
#include <ImfHeader.h>
#include <ImfInputFile.h>
#include <ImfRgbaFile.h>
#include <OpenImageIO/filesystem.h>
#include <OpenImageIO/imageio.h>

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cfloat>
#include <cmath>
#include <cstring>
#include <memory>
#include <new>
#include <string>
#include <vector>
#include <vector>

namespace
{

using OIIO::ImageInput;
using OIIO::ImageOutput;
using OIIO::ImageSpec;
using OIIO::TypeDesc;

/* One short line: OIIO messages can span several and repeat per strip. */
std::string one_line(std::string s)
{
    if (s.size() > 240)
        s = s.substr(0, 240) + "...";
    for (char &c : s)
        if (c == '\n' || c == '\r')
            c = ' ';
    while (!s.empty() && s.back() == ' ')
        s.pop_back();
    return s.empty() ? std::string("no detail") : s;
}

ImageSpec read_config()
{
    ImageSpec config;
    config.attribute("oiio:UnassociatedAlpha", 1);
    config.attribute("raw:ColorSpace", "sRGB-linear");
    config.attribute("raw:use_camera_wb", 1);
    config.attribute("raw:auto_bright", 0);
    config.attribute("raw:HighlightMode", 0);
    config.attribute("raw:user_flip", 0);
    config.attribute("raw:Demosaic", "AHD");
    return config;
}

sl_result open_input(const char *path, std::unique_ptr<ImageInput> &in, sl_error *err)
{
    sl_result r = sl_check_input_file(path, err);
    if (r)
        return r;
    ImageSpec config = read_config();
    in = ImageInput::open(path, &config);
    if (!in)
        return sl_error_set(err, SL_ERR_INPUT,
                            "%s: not an image file OIIO or OpenEXR can read (%s)", path,
                            one_line(OIIO::geterror()).c_str());
    return SL_OK;
}

/* A JPEG's MCU from its sampling factors ("4:2:0" and so on, as
 * OpenImageIO reports them): 8 pixels times the largest factor each way;
 * a grey JPEG (no chroma) has 8x8. */
void jpeg_block(const ImageSpec &spec, int *w, int *h)
{
    std::string s = spec.get_string_attribute("jpeg:subsampling");
    *w = *h = 8;
    if (s == "4:2:0")
        *w = *h = 16;
    else if (s == "4:2:2")
        *w = 16;
    else if (s == "4:1:1")
        *w = 32;
}

double number(const ImageSpec &spec, const char *name)
{
    const OIIO::ParamValue *p = spec.find_attribute(name);
    return p ? p->get_float() : 0.0;
}

void copy_string(char *dst, size_t size, const std::string &src)
{
    std::snprintf(dst, size, "%s", src.c_str());
}

sl_result fill_meta(const char *path, ImageInput &in, const ImageSpec &spec, sl_meta *meta,
                    sl_error *err)
{
    copy_string(meta->format, sizeof meta->format, in.format_name());
    meta->is_float = spec.format.is_floating_point();
    meta->bits_per_sample =
        spec.get_int_attribute("oiio:BitsPerSample", (int)spec.format.size() * 8);
    copy_string(meta->colorspace, sizeof meta->colorspace,
                spec.get_string_attribute("oiio:ColorSpace"));
    /* A linear export says so in its ICC profile (core/icc.c), more
     * precisely than the EXIF ColorSpace tag OIIO reads as "sRGB". */
    const OIIO::ParamValue *icc = spec.find_attribute("ICCProfile");
    if (icc && icc->type().basetype == TypeDesc::UINT8) {
        const char *linear = sl_icc_linear_space((const unsigned char *)icc->data(),
                                                 (size_t)icc->type().numelements());
        if (linear)
            copy_string(meta->colorspace, sizeof meta->colorspace, linear);
    }
    meta->exposure_time = number(spec, "ExposureTime");
    meta->f_number = number(spec, "FNumber");
    meta->iso = number(spec, "Exif:PhotographicSensitivity");
    if (meta->iso <= 0)
        meta->iso = number(spec, "Exif:ISOSpeedRatings");
    meta->focal_length_mm = number(spec, "Exif:FocalLength");
    copy_string(meta->make, sizeof meta->make, spec.get_string_attribute("Make"));
    copy_string(meta->model, sizeof meta->model, spec.get_string_attribute("Model"));
    std::string lens = spec.get_string_attribute("Exif:LensModel");
    if (lens.empty())
        lens = spec.get_string_attribute("LensModel");
    copy_string(meta->lens, sizeof meta->lens, lens);
    std::string when = spec.get_string_attribute("Exif:DateTimeOriginal");
    if (when.empty())
        when = spec.get_string_attribute("DateTime");
    copy_string(meta->datetime, sizeof meta->datetime, when);
    int orientation = spec.get_int_attribute("Orientation", 0);
    meta->orientation = orientation >= 1 && orientation <= 8 ? orientation : 0;
    /* setlight's own provenance, e.g. from PNG text chunks. */
    for (const OIIO::ParamValue &p : spec.extra_attribs) {
        if (p.type() != TypeDesc::STRING || std::strncmp(p.name().c_str(), "setlight:", 9) != 0)
            continue;
        if (sl_meta_set(meta, p.name().c_str(), p.get_string().c_str(), nullptr))
            return sl_error_set(err, SL_ERR_NOMEM, "%s: out of memory for metadata", path);
    }
    return SL_OK;
}

/* Formats photo_claim.c does not know (camera raw, BMP, ...) are checked
 * against the memory budget here, before their pixels are decoded. */
sl_result check_budget(const char *path, const ImageSpec &spec, int channels, sl_error *err)
{
    if (spec.width <= 0 || spec.height <= 0)
        return SL_OK; /* sl_image_alloc says what is wrong */
    char what[96];
    std::snprintf(what, sizeof what, "a %dx%d %s image", spec.width, spec.height,
                  spec.format.c_str());
    return sl_memory_check((uint64_t)spec.width * (uint64_t)spec.height * (uint64_t)channels *
                               sizeof(float),
                           path, what, err);
}

sl_result read_impl(const char *path, sl_image *img, sl_meta *meta, sl_error *err)
{
    std::unique_ptr<ImageInput> in;
    sl_result r = open_input(path, in, err);
    if (r)
        return r;
    const ImageSpec &spec = in->spec();
    int channels = spec.nchannels < 4 ? spec.nchannels : 4;
    if (spec.depth > 1)
        return sl_error_set(err, SL_ERR_INPUT, "%s: volume images are not supported", path);
    if ((r = check_budget(path, spec, channels, err)) != SL_OK)
        return r;
    r = sl_image_alloc(img, spec.width, spec.height, channels, nullptr);
    if (r)
        return sl_error_set(err, r, "%s: cannot hold a %dx%d image with %d channels", path,
                            spec.width, spec.height, spec.nchannels);
    /* Some readers (TIFF) report a short strip as an error yet return true. */
    if (!in->read_image(0, 0, 0, channels, TypeDesc::FLOAT, img->data) || in->has_error()) {
        std::string why = one_line(in->geterror());
        sl_image_free(img);
        return sl_error_set(err, SL_ERR_INPUT, "%s: truncated or corrupt image (%s)", path,
                            why.c_str());
    }
    if (meta && (r = fill_meta(path, *in, spec, meta, err)) != SL_OK)
        return r;
    in->close();
    return SL_OK;
}

sl_result read_meta_impl(const char *path, sl_meta *meta, int *width, int *height, int *channels,
                         sl_error *err)
{
    std::unique_ptr<ImageInput> in;
    sl_result r = open_input(path, in, err);
    if (r)
        return r;
    const ImageSpec &spec = in->spec();
    if (meta && (r = fill_meta(path, *in, spec, meta, err)) != SL_OK)
        return r;
    if (width)
        *width = spec.width;
    if (height)
        *height = spec.height;
    if (channels)
        *channels = spec.nchannels < 4 ? spec.nchannels : 4;
    in->close();
    return SL_OK;
}

bool ends_with(const std::string &s, const char *suffix)
{
    size_t n = std::strlen(suffix);
    if (s.size() < n)
        return false;
    for (size_t i = 0; i < n; i++)
        if (std::tolower((unsigned char)s[s.size() - n + i]) != suffix[i])
            return false;
    return true;
}

void set_exif(ImageSpec &spec, const sl_meta *meta)
{
    if (meta->exposure_time > 0) {
        /* OIIO 2.4's float_to_rational writes inf to JPEG EXIF when 1/t is
         * a whole number in float (1/2, 1/16 s); one ulp off avoids it. */
        float t = (float)meta->exposure_time;
        if (t < 1.0f && 1.0f / t == std::floor(1.0f / t))
            t = std::nextafter(t, 0.0f);
        spec.attribute("ExposureTime", t);
    }
    if (meta->f_number > 0)
        spec.attribute("FNumber", (float)meta->f_number);
    if (meta->iso > 0) {
        /* EXIF tag 0x8827 (ISOSpeedRatings is its old name) is a SHORT.
         * OIIO 2.4 round-trips it in JPEG but not in TIFF. */
        double iso = meta->iso < 65535 ? meta->iso : 65535;
        unsigned short iso16 = (unsigned short)std::lround(iso);
        spec.attribute("Exif:PhotographicSensitivity", TypeDesc::UINT16, &iso16);
    }
    if (meta->focal_length_mm > 0)
        spec.attribute("Exif:FocalLength", (float)meta->focal_length_mm);
    if (meta->make[0])
        spec.attribute("Make", meta->make);
    if (meta->model[0])
        spec.attribute("Model", meta->model);
    if (meta->lens[0])
        spec.attribute("Exif:LensModel", meta->lens);
    if (meta->datetime[0]) {
        spec.attribute("DateTime", meta->datetime);
        spec.attribute("Exif:DateTimeOriginal", meta->datetime);
    }
    if (meta->orientation >= 1 && meta->orientation <= 8)
        spec.attribute("Orientation", meta->orientation);
    for (int i = 0; i < meta->attr_count; i++)
        if (std::strncmp(meta->attrs[i].name, "setlight:", 9) == 0)
            spec.attribute(meta->attrs[i].name, meta->attrs[i].value);
}

sl_result write_impl(const char *path, const sl_image *img, const sl_meta *meta, int bits,
                     sl_error *err)
{
    if (!path || !*path)
        return sl_error_set(err, SL_ERR_USAGE, "empty output path");
    if (!img || !img->data || img->width <= 0 || img->height <= 0 || img->channels < 1 ||
        img->channels > 4)
        return sl_error_set(err, SL_ERR_USAGE, "%s: no image to write", path);
    std::string p(path);
    bool jpeg = ends_with(p, ".jpg") || ends_with(p, ".jpeg");
    bool png = ends_with(p, ".png");
    bool tiff = ends_with(p, ".tif") || ends_with(p, ".tiff");
    if (!jpeg && !png && !tiff)
        return sl_error_set(err, SL_ERR_USAGE,
                            "%s: unknown photo extension (use .png, .jpg, .jpeg, .tif, .tiff)",
                            path);
    bool bits_ok = jpeg  ? bits == 8
                   : png ? (bits == 8 || bits == 16)
                         : (bits == 8 || bits == 16 || bits == 32);
    if (!bits_ok)
        return sl_error_set(err, SL_ERR_USAGE,
                            "%s: %d bits per sample not possible for this format", path, bits);

    /* JPEG has no alpha: keep the colour channels only. */
    int nc = img->channels;
    if (jpeg && (nc == 2 || nc == 4))
        nc -= 1;
    TypeDesc type = bits == 8 ? TypeDesc::UINT8 : bits == 16 ? TypeDesc::UINT16 : TypeDesc::FLOAT;
    ImageSpec spec(img->width, img->height, nc, type);
    if (nc == 2 || nc == 4) {
        spec.alpha_channel = nc - 1;
        /* Pixels are written as given: no un-premultiplying by alpha. */
        spec.attribute("oiio:UnassociatedAlpha", 1);
    }
    if (jpeg)
        spec.attribute("CompressionQuality", 95);
    if (tiff)
        spec.attribute("compression", "zip");
    if (meta)
        set_exif(spec, meta);
    /* A TIFF of linear Rec.709 data carries the profile a raw converter's
     * linear export has, so readers (ingest among them) know it is linear. */
    unsigned char icc[1024];
    size_t icc_size = 0;
    if (tiff && bits != 32 && meta && meta->colorspace[0] &&
        sl_color_space_name(meta->colorspace) &&
        !std::strcmp(sl_color_space_name(meta->colorspace), SL_WORKING_SPACE) &&
        (icc_size = sl_icc_linear_rec709(icc, sizeof icc)) <= sizeof icc)
    {
        spec.attribute("ICCProfile", TypeDesc(TypeDesc::UINT8, (int)icc_size), icc);
        spec.attribute("Exif:ColorSpace", 0xFFFF); /* uncalibrated: not sRGB */
    }

    /* Integer formats clamp to [0, 1]; no NaN or Inf ever reaches a file. */
    std::vector<float> pixels((size_t)img->width * (size_t)img->height * (size_t)nc);
    float lo = bits == 32 ? -FLT_MAX : 0.0f, hi = bits == 32 ? FLT_MAX : 1.0f;
    for (int y = 0; y < img->height; y++)
        for (int x = 0; x < img->width; x++) {
            const float *src = sl_image_pixel(img, x, y);
            float *dst = &pixels[((size_t)y * (size_t)img->width + (size_t)x) * (size_t)nc];
            for (int c = 0; c < nc; c++) {
                float v = src[c];
                dst[c] = std::isnan(v) ? 0.0f : v < lo ? lo : v > hi ? hi : v;
            }
        }

    sl_atomic_file f;
    sl_result r = sl_atomic_begin(&f, path, err);
    if (r)
        return r;
    std::string why;
    bool ok = false, in_memory = false;
    /* PNG and JPEG are encoded in memory, then written here: OIIO's PNG
     * writer ignores a failed write (disk full gave a truncated PNG and
     * success). Not TIFF: libtiff seeks back, which OIIO 2.4's memory
     * output gets wrong (a TIFF without its ImageLength). */
    std::vector<unsigned char> bytes;
    OIIO::Filesystem::IOVecOutput vec(bytes);
    try {
        std::unique_ptr<ImageOutput> out = ImageOutput::create(f.temp_path);
        in_memory = (png || jpeg) && out && out->supports("ioproxy") && out->set_ioproxy(&vec);
        ok =
            out && out->open(f.temp_path, spec) && out->write_image(TypeDesc::FLOAT, pixels.data());
        if (out) {
            if (!ok)
                why = out->geterror();
            ok = out->close() && ok;
            if (!ok && why.empty())
                why = out->geterror();
        } else {
            why = OIIO::geterror();
        }
    } catch (...) {
        sl_atomic_abort(&f);
        throw;
    }
    if (!ok) {
        sl_atomic_abort(&f);
        return sl_error_set(err, SL_ERR_IO, "%s: cannot write image (%s)", path,
                            one_line(why).c_str());
    }
    if (in_memory) {
        FILE *fp = fopen(f.temp_path, "wb");
        bool wrote = fp && fwrite(bytes.data(), 1, bytes.size(), fp) == bytes.size();
        int e = errno;
        if (fp && fclose(fp) != 0 && wrote) {
            wrote = false;
            e = errno;
        }
        if (!wrote) {
            sl_atomic_abort(&f);
            return sl_error_set(err, SL_ERR_IO, "%s: write failed: %s", path, strerror(e));
        }
    }
    return sl_atomic_commit(&f, err);
}

/* OpenEXR's C++ library, which OpenImageIO links (OpenImageIO itself
 * refuses a file with any subsampled channel), a strip of rows at a time:
 * only the picked channels are decoded, others are skipped by the library. */
/* Luminance/chroma files (Y, RY, BY: chroma subsampled) back to R, G, B
 * (and A) through OpenEXR's RGBA interface, which knows the file's
 * chromaticities and chroma filter. */
sl_result exr_yc_pixels(const char *path, int count, int x0, int y0, sl_image *img)
{
    Imf::RgbaInputFile in(path, sl_threads_get());
    const Imath::Box2i &dw = in.dataWindow();
    int64_t w = (int64_t)dw.max.x - dw.min.x + 1;
    int first = std::max(dw.min.y, y0), last = std::min(dw.max.y, y0 + img->height - 1);
    int strip = 64;
    std::vector<Imf::Rgba> rows((size_t)w * (size_t)strip);
    for (int ys = first; ys <= last; ys += strip) {
        int ye = std::min(ys + strip - 1, last);
        /* The frame buffer is addressed by file coordinates: shift the
         * strip's base by the strip's origin, in integers. */
        intptr_t origin = (intptr_t)dw.min.x + (intptr_t)ys * (intptr_t)w;
        in.setFrameBuffer((Imf::Rgba *)((uintptr_t)rows.data() - (uintptr_t)origin * sizeof(Imf::Rgba)),
                          1, (size_t)w);
        in.readPixels(ys, ye);
        for (int y = ys; y <= ye; y++)
            for (int64_t x = std::max<int64_t>(dw.min.x, x0);
                 x <= std::min<int64_t>(dw.max.x, (int64_t)x0 + img->width - 1); x++) {
                const Imf::Rgba &p = rows[(size_t)(y - ys) * (size_t)w + (size_t)(x - dw.min.x)];
                float *dst = sl_image_pixel(img, (int)(x - x0), y - y0);
                const float v[4] = {p.r, p.g, p.b, p.a};
                for (int c = 0; c < count; c++)
                    dst[c] = v[c];
            }
    }
    return SL_OK;
}

sl_result exr_pixels_impl(const char *path, const char *const *names, int count, int x0, int y0,
                          sl_image *img)
{
    Imf::InputFile in(path, sl_threads_get());
    const Imf::ChannelList &channels = in.header().channels();
    if (!channels.findChannel("R") && channels.findChannel("Y") &&
        (channels.findChannel("RY") || channels.findChannel("BY")))
        return exr_yc_pixels(path, count, x0, y0, img);
    const Imath::Box2i &dw = in.header().dataWindow();
    int64_t w = (int64_t)dw.max.x - dw.min.x + 1;
    /* The rows of the data window inside the display window. */
    int first = std::max(dw.min.y, y0), last = std::min(dw.max.y, y0 + img->height - 1);
    int strip = 64;
    std::vector<float> rows((size_t)w * (size_t)strip * (size_t)count);
    for (int ys = first; ys <= last; ys += strip) {
        int ye = std::min(ys + strip - 1, last);
        Imf::FrameBuffer fb;
        for (int c = 0; c < count; c++)
            fb.insert(names[c], Imf::Slice::Make(Imf::FLOAT, &rows[(size_t)c * (size_t)w * (size_t)strip],
                                                 Imath::V2i(dw.min.x, ys), w, strip));
        in.setFrameBuffer(fb);
        in.readPixels(ys, ye);
        for (int y = ys; y <= ye; y++)
            for (int64_t x = std::max<int64_t>(dw.min.x, x0);
                 x <= std::min<int64_t>(dw.max.x, (int64_t)x0 + img->width - 1); x++) {
                float *dst = sl_image_pixel(img, (int)(x - x0), y - y0);
                size_t at = (size_t)(y - ys) * (size_t)w + (size_t)(x - dw.min.x);
                for (int c = 0; c < count; c++)
                    dst[c] = rows[(size_t)c * (size_t)w * (size_t)strip + at];
            }
    }
    return SL_OK;
}

/* The library's exceptions on a bad file are the file's problem (exit 3). */
sl_result exr_pixels_checked(const char *path, const char *const *names, int count, int x0, int y0,
                             sl_image *img, sl_error *err)
{
    try {
        return exr_pixels_impl(path, names, count, x0, y0, img);
    } catch (const std::bad_alloc &) {
        throw;
    } catch (const std::exception &e) {
        return sl_error_set(err, SL_ERR_INPUT, "%s: truncated or corrupt EXR (%s)", path,
                            one_line(e.what()).c_str());
    }
}

sl_result exception_error(const char *path, sl_error *err, const char *what, bool nomem)
{
    return sl_error_set(err, nomem ? SL_ERR_NOMEM : SL_ERR_INTERNAL, "%s: OpenImageIO failed (%s)",
                        path ? path : "(null)", what);
}

} // namespace

extern "C" sl_result sl_photo_read(const char *path, sl_image *img, sl_meta *meta, sl_error *err)
{
    std::memset(img, 0, sizeof *img);
    if (meta)
        sl_meta_init(meta);
    sl_result r;
    try {
        r = read_impl(path, img, meta, err);
    } catch (const std::bad_alloc &) {
        r = exception_error(path, err, "out of memory", true);
    } catch (const std::exception &e) {
        r = exception_error(path, err, e.what(), false);
    } catch (...) {
        r = exception_error(path, err, "unknown exception", false);
    }
    if (r) {
        sl_image_free(img);
        if (meta)
            sl_meta_free(meta);
    }
    return r;
}

extern "C" sl_result sl_photo_read_meta(const char *path, sl_meta *meta, int *width, int *height,
                                        int *channels, sl_error *err)
{
    if (meta)
        sl_meta_init(meta);
    if (width)
        *width = 0;
    if (height)
        *height = 0;
    if (channels)
        *channels = 0;
    sl_result r;
    try {
        r = read_meta_impl(path, meta, width, height, channels, err);
    } catch (const std::bad_alloc &) {
        r = exception_error(path, err, "out of memory", true);
    } catch (const std::exception &e) {
        r = exception_error(path, err, e.what(), false);
    } catch (...) {
        r = exception_error(path, err, "unknown exception", false);
    }
    if (r && meta)
        sl_meta_free(meta);
    return r;
}

extern "C" sl_result sl_exr_read_pixels_oiio(const char *path, const char *const *names, int count,
                                             int x0, int y0, sl_image *img, sl_error *err)
{
    try {
        return exr_pixels_checked(path, names, count, x0, y0, img, err);
    } catch (const std::bad_alloc &) {
        return exception_error(path, err, "out of memory", true);
    } catch (const std::exception &e) {
        return exception_error(path, err, e.what(), false);
    } catch (...) {
        return exception_error(path, err, "unknown exception", false);
    }
}

extern "C" sl_result sl_photo_write(const char *path, const sl_image *img, const sl_meta *meta,
                                    int bits, sl_error *err)
{
    try {
        return write_impl(path, img, meta, bits, err);
    } catch (const std::bad_alloc &) {
        return exception_error(path, err, "out of memory", true);
    } catch (const std::exception &e) {
        return exception_error(path, err, e.what(), false);
    } catch (...) {
        return exception_error(path, err, "unknown exception", false);
    }
}

/* ------------------------------------------------------------------ */
/* Strips: the same opening, a few rows at a time                      */
/* ------------------------------------------------------------------ */

struct sl_photo_strips {
    std::unique_ptr<ImageInput> in;
    std::string path;
    int width = 0, channels = 0, code_bytes = 0;
    std::vector<float> scratch;
    std::vector<unsigned char> code_scratch, tile_rows;
};

/* Rows y0..y1-1 of the file's first channels. OIIO 2.4's read_scanlines
 * divides by zero on some tiled TIFFs (one whose photometric core's own
 * reader declines: fuzz_photo), so a tiled file is read a row of tiles at a
 * time through read_tiles, which reads those files. */
static bool read_rows(sl_photo_strips *s, int y0, int y1, TypeDesc type, void *dst)
{
    const ImageSpec &spec = s->in->spec();
    if (spec.tile_width <= 0 || spec.tile_height <= 0)
        return s->in->read_scanlines(0, 0, y0, y1, 0, 0, s->channels, type, dst);
    size_t px = type.size() * (size_t)s->channels, row = px * (size_t)spec.width;
    int th = spec.tile_height;
    int t0 = y0 - y0 % th, t1 = std::min(spec.height, ((y1 + th - 1) / th) * th);
    s->tile_rows.resize(row * (size_t)(t1 - t0));
    if (!s->in->read_tiles(0, 0, spec.x, spec.x + spec.width, spec.y + t0, spec.y + t1, spec.z,
                           spec.z + 1, 0, s->channels, type, s->tile_rows.data()))
        return false;
    std::memcpy(dst, s->tile_rows.data() + row * (size_t)(y0 - t0), row * (size_t)(y1 - y0));
    return true;
}

/* Formats that store integer codes exactly (a TIFF unless JPEG-compressed);
 * any other (JPEG, HEIF, WebP, JPEG 2000, ...) may ring below the clip. */
static bool lossless_format(const char *format, const ImageSpec &spec)
{
    static const char *const exact[] = {"png", "pnm", "bmp", "targa", "sgi"};
    for (const char *f : exact)
        if (std::strcmp(format, f) == 0)
            return true;
    return std::strcmp(format, "tiff") == 0 &&
           spec.get_string_attribute("compression").find("jpeg") == std::string::npos;
}

extern "C" sl_result sl_photo_strips_open(const char *path, sl_photo_strips **strips,
                                          sl_photo_strip_info *info, sl_error *err)
{
    *strips = nullptr;
    std::memset(info, 0, sizeof *info);
    try {
        std::unique_ptr<sl_photo_strips> s(new sl_photo_strips);
        sl_result r = open_input(path, s->in, err);
        if (r)
            return r;
        const ImageSpec &spec = s->in->spec();
        if (spec.depth > 1 || spec.nchannels < 1)
            return sl_error_set(err, SL_ERR_INPUT, "%s: not a 2D image with colour channels", path);
        s->path = path;
        s->width = spec.width;
        s->channels = spec.nchannels >= 3 ? 3 : 1;
        info->width = spec.width;
        info->height = spec.height;
        info->file_channels = spec.nchannels;
        info->is_float = spec.format.basetype == TypeDesc::FLOAT ||
                         spec.format.basetype == TypeDesc::HALF ||
                         spec.format.basetype == TypeDesc::DOUBLE;
        info->bits = spec.get_int_attribute("oiio:BitsPerSample", (int)spec.format.size() * 8);
        if (spec.format.basetype == TypeDesc::UINT8 || spec.format.basetype == TypeDesc::UINT16)
            s->code_bytes = info->code_bytes = (int)spec.format.size();
        if (std::strcmp(s->in->format_name(), "jpeg") == 0)
            jpeg_block(spec, &info->block_w, &info->block_h);
        info->lossless = info->code_bytes > 0 && lossless_format(s->in->format_name(), spec);
        *strips = s.release();
        return SL_OK;
    } catch (const std::bad_alloc &e) {
        return exception_error(path, err, e.what(), true);
    } catch (const std::exception &e) {
        return exception_error(path, err, e.what(), false);
    }
}

extern "C" sl_result sl_photo_strips_read(sl_photo_strips *s, int y0, int y1, float *rgb,
                                          sl_error *err)
{
    size_t n = (size_t)(y1 - y0) * (size_t)s->width;
    float *dst = rgb;
    if (s->channels == 1) {
        try {
            s->scratch.resize(n);
        } catch (...) {
            return sl_error_set(err, SL_ERR_NOMEM, "%s: out of memory", s->path.c_str());
        }
        dst = s->scratch.data();
    }
    /* Some readers (TIFF) report a short strip as an error yet return true. */
    if (!read_rows(s, y0, y1, TypeDesc::FLOAT, dst) || s->in->has_error()) {
        std::string why = one_line(s->in->geterror());
        return sl_error_set(err, SL_ERR_INPUT, "%s: truncated or corrupt image at rows %d-%d (%s)",
                            s->path.c_str(), y0, y1 - 1, why.c_str());
    }
    if (s->channels == 1)
        for (size_t i = n; i-- > 0;)
            rgb[3 * i] = rgb[3 * i + 1] = rgb[3 * i + 2] = dst[i];
    return SL_OK;
}

extern "C" sl_result sl_photo_strips_read_codes(sl_photo_strips *s, int y0, int y1, void *rgb,
                                                sl_error *err)
{
    if (!s->code_bytes)
        return sl_error_set(err, SL_ERR_USAGE, "%s: no integer codes (float samples)",
                            s->path.c_str());
    size_t n = (size_t)(y1 - y0) * (size_t)s->width, b = (size_t)s->code_bytes;
    unsigned char *dst = (unsigned char *)rgb;
    if (s->channels == 1) {
        try {
            s->code_scratch.resize(n * b);
        } catch (...) {
            return sl_error_set(err, SL_ERR_NOMEM, "%s: out of memory", s->path.c_str());
        }
        dst = s->code_scratch.data();
    }
    TypeDesc type = b == 1 ? TypeDesc::UINT8 : TypeDesc::UINT16;
    if (!read_rows(s, y0, y1, type, dst) || s->in->has_error()) {
        std::string why = one_line(s->in->geterror());
        return sl_error_set(err, SL_ERR_INPUT, "%s: truncated or corrupt image at rows %d-%d (%s)",
                            s->path.c_str(), y0, y1 - 1, why.c_str());
    }
    unsigned char *out = (unsigned char *)rgb;
    if (s->channels == 1)
        for (size_t i = n; i-- > 0;)
            for (int c = 0; c < 3; c++)
                std::memcpy(out + (3 * i + (size_t)c) * b, dst + i * b, b);
    return SL_OK;
}

extern "C" void sl_photo_strips_close(sl_photo_strips *s)
{
    if (!s)
        return;
    if (s->in)
        s->in->close();
    delete s;
}
