// SPDX-License-Identifier: BSD-3-Clause
// Colour-space conversion through OpenColorIO 2.1 behind the C functions of
// core.h. No exception crosses into C: every OCIO call is wrapped and turned
// into an sl_error.
//
// A config is loaded once per path and kept for the life of the process, so
// the names handed out by sl_color_space_name / sl_color_space_list stay
// valid, and pointing SETLIGHT_OCIO_CONFIG elsewhere takes effect at the next
// call. A config that fails to load is not remembered: the next call retries
// and reports the error again.
#include "setlight/core.h"

#include <OpenColorIO/OpenColorIO.h>

#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <strings.h>
#include <utility>
#include <vector>

namespace OCIO = OCIO_NAMESPACE;

namespace {

struct loaded_config {
    std::string path;
    OCIO::ConstConfigRcPtr config;
    std::vector<std::string> names;         // canonical names, config order
    std::vector<std::string> encodings;     // per name: OCIO encoding, "data" for data spaces
    std::vector<const char *> list;         // names as C strings, NULL-terminated
    std::vector<std::pair<std::string, size_t>> lookup; // name, alias or role -> names index
    std::mutex processors_lock;
    std::map<std::pair<size_t, size_t>, OCIO::ConstCPUProcessorRcPtr> processors;
};

std::mutex configs_lock;
std::vector<std::unique_ptr<loaded_config>> configs;
std::once_flag logging_once;
const char *const empty_list[] = {nullptr};

// OCIO would print its warnings to stderr; libraries report through sl_log.
void ocio_log(const char *message)
{
    std::string m(message ? message : "");
    while (!m.empty() && (m.back() == '\n' || m.back() == '\r'))
        m.pop_back();
    sl_log(SL_LOG_DEBUG, "OpenColorIO: %s", m.c_str());
}

const char *config_origin()
{
    const char *env = std::getenv("SETLIGHT_OCIO_CONFIG");
    return env && *env ? "set by SETLIGHT_OCIO_CONFIG" : "setlight's shipped config";
}

void index_config(loaded_config &lc)
{
    const OCIO::Config &cfg = *lc.config;
    int n = cfg.getNumColorSpaces(OCIO::SEARCH_REFERENCE_SPACE_ALL, OCIO::COLORSPACE_ALL);
    for (int i = 0; i < n; i++) {
        const char *name = cfg.getColorSpaceNameByIndex(OCIO::SEARCH_REFERENCE_SPACE_ALL,
                                                        OCIO::COLORSPACE_ALL, i);
        lc.names.emplace_back(name);
        OCIO::ConstColorSpaceRcPtr cs = cfg.getColorSpace(name);
        lc.encodings.emplace_back(!cs ? "" : cs->isData() ? "data" : cs->getEncoding());
    }
    for (size_t i = 0; i < lc.names.size(); i++) {
        lc.lookup.emplace_back(lc.names[i], i);
        OCIO::ConstColorSpaceRcPtr cs = cfg.getColorSpace(lc.names[i].c_str());
        for (size_t a = 0; cs && a < cs->getNumAliases(); a++)
            lc.lookup.emplace_back(cs->getAlias(a), i);
    }
    // Roles (scene_linear, data, ...) resolve to the colour space they name.
    for (int r = 0; r < cfg.getNumRoles(); r++) {
        const char *role = cfg.getRoleName(r);
        OCIO::ConstColorSpaceRcPtr cs = cfg.getColorSpace(role);
        if (!cs)
            continue;
        for (size_t i = 0; i < lc.names.size(); i++)
            if (lc.names[i] == cs->getName())
                lc.lookup.emplace_back(role, i);
    }
    for (const std::string &s : lc.names)
        lc.list.push_back(s.c_str());
    lc.list.push_back(nullptr);
}

// The config at sl_color_config_path(), loaded on first use.
loaded_config *get_config(sl_error *err)
{
    const char *path = sl_color_config_path();
    std::lock_guard<std::mutex> guard(configs_lock);
    for (const auto &c : configs)
        if (c->path == path)
            return c.get();

    sl_error check;
    sl_result r = sl_check_input_file(path, &check);
    if (r != SL_OK) {
        sl_error_set(err, r, "%s (OCIO colour config, %s)", check.message, config_origin());
        return nullptr;
    }
    try {
        std::call_once(logging_once, [] { OCIO::SetLoggingFunction(ocio_log); });
        auto lc = std::make_unique<loaded_config>();
        lc->path = path;
        lc->config = OCIO::Config::CreateFromFile(path);
        lc->config->validate();
        index_config(*lc);
        if (lc->names.empty()) {
            sl_error_set(err, SL_ERR_INPUT, "%s: OCIO colour config has no colour spaces (%s)",
                         path, config_origin());
            return nullptr;
        }
        configs.push_back(std::move(lc));
        return configs.back().get();
    } catch (const std::bad_alloc &) {
        sl_error_set(err, SL_ERR_NOMEM, "%s: out of memory loading the OCIO colour config", path);
    } catch (const std::exception &e) {
        sl_error_set(err, SL_ERR_INPUT, "%s: invalid OCIO colour config (%s): %s", path,
                     config_origin(), e.what());
    }
    return nullptr;
}

// Index into lc.names, or -1.
long find_space(const loaded_config &lc, const char *name)
{
    if (!name)
        return -1;
    for (const auto &entry : lc.lookup)
        if (strcasecmp(entry.first.c_str(), name) == 0)
            return (long)entry.second;
    return -1;
}

sl_result unknown_space(const loaded_config &lc, const char *name, sl_error *err)
{
    std::string known;
    for (const std::string &s : lc.names)
        known += (known.empty() ? "" : ", ") + s;
    return sl_error_set(err, SL_ERR_USAGE, "unknown colour space '%s' (known: %s)",
                        name ? name : "(null)", known.c_str());
}

OCIO::ConstCPUProcessorRcPtr get_processor(loaded_config &lc, size_t from, size_t to,
                                           sl_error *err)
{
    std::lock_guard<std::mutex> guard(lc.processors_lock);
    auto key = std::make_pair(from, to);
    auto it = lc.processors.find(key);
    if (it != lc.processors.end())
        return it->second;
    try {
        OCIO::ConstProcessorRcPtr p =
            lc.config->getProcessor(lc.names[from].c_str(), lc.names[to].c_str());
        // Lossless: exact pow/log instead of the fast SSE approximations, so
        // the sRGB curve agrees with sl_linear_to_srgb to float precision.
        OCIO::ConstCPUProcessorRcPtr cpu = p->getOptimizedCPUProcessor(
            OCIO::BIT_DEPTH_F32, OCIO::BIT_DEPTH_F32, OCIO::OPTIMIZATION_LOSSLESS);
        lc.processors.emplace(key, cpu);
        return cpu;
    } catch (const std::bad_alloc &) {
        sl_error_set(err, SL_ERR_NOMEM, "%s: out of memory building the OCIO processor",
                     lc.path.c_str());
    } catch (const std::exception &e) {
        sl_error_set(err, SL_ERR_INPUT, "%s: cannot convert '%s' to '%s': %s", lc.path.c_str(),
                     lc.names[from].c_str(), lc.names[to].c_str(), e.what());
    }
    return nullptr;
}

struct convert_job {
    sl_image *img;
    const OCIO::CPUProcessor *cpu;
    std::mutex lock;
    bool failed = false;
    std::string message;
};

// The display and view by their config names (case-insensitive match), or
// a usage error listing what the config has.
sl_result find_display_view(const loaded_config &lc, const char *display, const char *view,
                            std::string &disp_name, std::string &view_name, sl_error *err)
{
    const OCIO::Config &cfg = *lc.config;
    std::string known;
    disp_name.clear();
    for (int i = 0; i < cfg.getNumDisplays(); i++) {
        const char *d = cfg.getDisplay(i);
        known += (known.empty() ? "" : ", ") + std::string(d);
        if (display ? strcasecmp(d, display) == 0 : strcmp(d, cfg.getDefaultDisplay()) == 0)
            disp_name = d;
    }
    if (disp_name.empty())
        return sl_error_set(err, SL_ERR_USAGE, "unknown display '%s' (known: %s)",
                            display ? display : "(default)", known.c_str());
    known.clear();
    view_name.clear();
    const char *dflt = cfg.getDefaultView(disp_name.c_str());
    for (int i = 0; i < cfg.getNumViews(disp_name.c_str()); i++) {
        const char *v = cfg.getView(disp_name.c_str(), i);
        known += (known.empty() ? "" : ", ") + std::string(v);
        if (view ? strcasecmp(v, view) == 0 : strcmp(v, dflt) == 0)
            view_name = v;
    }
    if (view_name.empty())
        return sl_error_set(err, SL_ERR_USAGE, "unknown view '%s' of display %s (known: %s)",
                            view ? view : "(default)", disp_name.c_str(), known.c_str());
    return SL_OK;
}

} // namespace

extern "C" {

static sl_result check_pixels(const sl_image *img, sl_error *err)
{
    if (!img || !img->data || img->width <= 0 || img->height <= 0 ||
        img->stride < (size_t)img->width * (size_t)(img->channels > 0 ? img->channels : 1))
        return sl_error_set(err, SL_ERR_USAGE, "colour conversion: empty or malformed image");
    // Converting one or two channels has no single right answer (grey as R=G=B
    // becomes non-grey in XYZ): callers expand them first with
    // sl_image_convert_channels.
    if (img->channels != 3 && img->channels != 4)
        return sl_error_set(err, SL_ERR_USAGE,
                            "colour conversion needs RGB or RGBA pixels, image has %d channel%s",
                            img->channels, img->channels == 1 ? "" : "s");
    return SL_OK;
}

static void convert_rows(void *ctx, int64_t begin, int64_t end, int worker)
{
    (void)worker;
    convert_job *job = static_cast<convert_job *>(ctx);
    sl_image *img = job->img;
    try {
        const ptrdiff_t chan = (ptrdiff_t)sizeof(float);
        OCIO::PackedImageDesc desc(img->data + (size_t)begin * img->stride, img->width,
                                   (long)(end - begin), img->channels, OCIO::BIT_DEPTH_F32, chan,
                                   chan * img->channels, chan * (ptrdiff_t)img->stride);
        job->cpu->apply(desc);
    } catch (const std::exception &e) {
        std::lock_guard<std::mutex> guard(job->lock);
        if (!job->failed) {
            job->failed = true;
            job->message = e.what();
        }
    }
}

static sl_result apply_processor(sl_image *img, const OCIO::CPUProcessor *cpu,
                                 const loaded_config &lc, const char *from, const char *to,
                                 sl_error *err)
{
    convert_job job;
    job.img = img;
    job.cpu = cpu;
    // About 64k pixels per chunk: large enough to amortise OCIO's per-call
    // setup, small enough to balance across threads. Each pixel is converted
    // on its own, so the result does not depend on the split.
    int64_t grain = 65536 / img->width;
    sl_parallel_for(img->height, grain > 0 ? grain : 1, convert_rows, &job);
    if (job.failed)
        return sl_error_set(err, SL_ERR_INTERNAL, "%s: converting '%s' to '%s' failed: %s",
                            lc.path.c_str(), from, to, job.message.c_str());
    return SL_OK;
}

const char *sl_color_config_path(void)
{
    const char *env = std::getenv("SETLIGHT_OCIO_CONFIG");
    if (env && *env)
        return env;
    return SETLIGHT_OCIO_CONFIG_DEFAULT;
}

// A space's canonical name or its encoding (a field of loaded_config).
static const char *space_field(const char *name, std::vector<std::string> loaded_config::*field)
{
    loaded_config *lc = get_config(nullptr);
    if (!lc)
        return nullptr;
    long i = find_space(*lc, name);
    return i < 0 ? nullptr : ((*lc).*field)[(size_t)i].c_str();
}

const char *sl_color_space_name(const char *name)
{
    return space_field(name, &loaded_config::names);
}

const char *sl_color_space_encoding(const char *name)
{
    return space_field(name, &loaded_config::encodings);
}

const char *const *sl_color_space_list(void)
{
    loaded_config *lc = get_config(nullptr);
    return lc ? lc->list.data() : empty_list;
}

// What every conversion starts with: the pixels checked (unless img is
// NULL), the config, the index of the source space; NULL with err set.
static loaded_config *open_conversion(const sl_image *img, const char *from, long *src,
                                      sl_error *err)
{
    if (img && check_pixels(img, err))
        return nullptr;
    loaded_config *lc = get_config(err);
    if (!lc)
        return nullptr;
    *src = find_space(*lc, from);
    if (*src < 0) {
        unknown_space(*lc, from, err);
        return nullptr;
    }
    return lc;
}

sl_result sl_color_convert(sl_image *img, const char *from, const char *to, sl_error *err)
{
    sl_error local; // the helpers report through err; its code is the result
    if (!err)
        err = &local;
    long src;
    loaded_config *lc = open_conversion(img, from, &src, err);
    if (!lc)
        return err->code;
    long dst = find_space(*lc, to);
    if (dst < 0)
        return unknown_space(*lc, to, err);
    if (src == dst)
        return SL_OK;

    OCIO::ConstCPUProcessorRcPtr cpu = get_processor(*lc, (size_t)src, (size_t)dst, err);
    if (!cpu)
        return err->code;
    if (cpu->isNoOp())
        return SL_OK;

    return apply_processor(img, cpu.get(), *lc, lc->names[(size_t)src].c_str(),
                           lc->names[(size_t)dst].c_str(), err);
}

sl_result sl_color_display_view(sl_image *img, const char *from, const char *display,
                                const char *view, char *applied, size_t applied_size,
                                sl_error *err)
{
    sl_error local;
    if (!err)
        err = &local;
    long src;
    loaded_config *lc = open_conversion(img, from, &src, err);
    if (!lc)
        return err->code;
    std::string disp_name, view_name;
    sl_result r;
    if ((r = find_display_view(*lc, display, view, disp_name, view_name, err)))
        return r;
    if (applied && applied_size)
        snprintf(applied, applied_size, "%s/%s", disp_name.c_str(), view_name.c_str());
    if (!img)
        return SL_OK;
    OCIO::ConstCPUProcessorRcPtr cpu;
    try {
        OCIO::DisplayViewTransformRcPtr t = OCIO::DisplayViewTransform::Create();
        t->setSrc(lc->names[(size_t)src].c_str());
        t->setDisplay(disp_name.c_str());
        t->setView(view_name.c_str());
        cpu = lc->config->getProcessor(t)->getOptimizedCPUProcessor(
            OCIO::BIT_DEPTH_F32, OCIO::BIT_DEPTH_F32, OCIO::OPTIMIZATION_LOSSLESS);
    } catch (const std::bad_alloc &) {
        return sl_error_set(err, SL_ERR_NOMEM, "%s: out of memory building the OCIO processor",
                            lc->path.c_str());
    } catch (const std::exception &e) {
        return sl_error_set(err, SL_ERR_INPUT, "%s: cannot show '%s' on %s/%s: %s",
                            lc->path.c_str(), lc->names[(size_t)src].c_str(), disp_name.c_str(),
                            view_name.c_str(), e.what());
    }
    if (cpu->isNoOp())
        return SL_OK;
    std::string to = disp_name + "/" + view_name;
    return apply_processor(img, cpu.get(), *lc, lc->names[(size_t)src].c_str(), to.c_str(), err);
}

} // extern "C"
