// SPDX-License-Identifier: BSD-3-Clause
// OpenEXR's C++ library behind C functions, for test_exr_layouts: it writes
// every compression OpenEXR 3.1 has (the 3.1 C API cannot encode DWAA/DWAB),
// subsampled channels and tiles, and decodes a channel as the reference the
// reader's pixels are compared with.
#include <ImfChannelList.h>
#include <ImfFrameBuffer.h>
#include <ImfHeader.h>
#include <ImfInputFile.h>
#include <ImfOutputFile.h>
#include <ImfTiledOutputFile.h>
#include <half.h>

#include <cstdio>
#include <exception>
#include <vector>

#include "exr_layouts.h"

namespace {

void say(char *why, size_t size, const char *what)
{
    if (why && size)
        std::snprintf(why, size, "%s", what);
}

} // namespace

extern "C" bool exr_layout_write(const char *path, const exr_layout *l, exr_layout_value value,
                                 char *why, size_t why_size)
{
    try {
        Imf::Header header(l->width, l->height);
        header.compression() = (Imf::Compression)l->compression;
        // Written from buffers of the channel's own type (OutputFile does not convert).
        std::vector<std::vector<float>> planes((size_t)l->nch);
        std::vector<std::vector<half>> halves((size_t)l->nch);
        Imf::FrameBuffer fb;
        for (int c = 0; c < l->nch; c++) {
            const exr_layout_channel &ch = l->channels[c];
            int xs = ch.sampling ? ch.sampling : 1, sw = l->width / xs, sh = l->height / xs;
            header.channels().insert(ch.name, Imf::Channel((Imf::PixelType)ch.type, xs, xs));
            std::vector<float> &p = planes[(size_t)c];
            p.resize((size_t)sw * (size_t)sh);
            for (int y = 0; y < sh; y++)
                for (int x = 0; x < sw; x++)
                    p[(size_t)y * (size_t)sw + (size_t)x] = value(c, x * xs, y * xs);
            if (ch.type == Imf::HALF) {
                std::vector<half> &hp = halves[(size_t)c];
                hp.assign(p.begin(), p.end());
                fb.insert(ch.name, Imf::Slice(Imf::HALF, (char *)hp.data(), sizeof(half),
                                              sizeof(half) * (size_t)sw, xs, xs));
            } else {
                fb.insert(ch.name, Imf::Slice(Imf::FLOAT, (char *)p.data(), sizeof(float),
                                              sizeof(float) * (size_t)sw, xs, xs));
            }
        }
        if (l->tile) {
            header.setTileDescription(Imf::TileDescription(l->tile, l->tile, Imf::ONE_LEVEL));
            Imf::TiledOutputFile out(path, header);
            out.setFrameBuffer(fb);
            out.writeTiles(0, out.numXTiles() - 1, 0, out.numYTiles() - 1);
        } else {
            Imf::OutputFile out(path, header);
            out.setFrameBuffer(fb);
            out.writePixels(l->height);
        }
        return true;
    } catch (const std::exception &e) {
        say(why, why_size, e.what());
    } catch (...) {
        say(why, why_size, "unknown exception");
    }
    return false;
}

extern "C" bool exr_layout_decode(const char *path, const char *name, float *out, int width,
                                  int height, char *why, size_t why_size)
{
    try {
        Imf::InputFile in(path);
        Imf::FrameBuffer fb;
        fb.insert(name, Imf::Slice(Imf::FLOAT, (char *)out, sizeof(float),
                                   sizeof(float) * (size_t)width));
        in.setFrameBuffer(fb);
        in.readPixels(0, height - 1);
        return true;
    } catch (const std::exception &e) {
        say(why, why_size, e.what());
    } catch (...) {
        say(why, why_size, "unknown exception");
    }
    return false;
}
