#include "shot_args.h"

#include "args.h"
#include "core/core.h"

#include <cmath>

namespace fulgur::app {

std::string shot_usage() {
    return "usage: fulgur-shot SCENE.json [--fgb FILE] --seed S --time T --size WxH -o OUT.png\n"
           "                   [--repeat N] [--exposure EV] [--reference REF.png]\n"
           "Renders one frame of SCENE's storm headless (OSMesa) to OUT.png and prints the\n"
           "per-stage timings as one JSON line.\n"
           "  --fgb FILE   baked bases to use (default: the scene's .fgb, baked first if missing or stale)\n"
           "  --seed S     strike seed (unsigned integer); a strike starts at t = 0\n"
           "  --time T     seconds after the strike start (>= 0); +T: T seconds after the first return\n"
           "               stroke's onset (the stepped leader's duration depends on the bolt)\n"
           "  --size WxH   image size in pixels (1..8192 each)\n"
           "  --repeat N   render the frame N times (1..1000) and report median stage times\n"
           "  --exposure EV  exposure change in stops from the default (0; -20..20)\n"
           "  -o OUT.png   output PNG\n"
           "  --reference REF.png  also render the frame lit by the direct solve (exact single\n"
           "               scattering + the scene's solver on the frame's point sources, no basis;\n"
           "               seconds) into REF.png, |difference| into REF_diff.png (white = 10% of\n"
           "               the reference's maximum), basis | direct | difference into REF_compare.png,\n"
           "               and print the errors and times as JSON\n"
           "  --help       this text\n";
}

namespace {
template <class T>
T parse_number(const std::string& s, const char* what) {
    return app::parse_number<T>(s, "fulgur-shot", what);
}
}  // namespace

ShotArgs parse_shot_args(const std::vector<std::string>& args) {
    ShotArgs a;
    bool have_seed = false, have_time = false, have_size = false, have_out = false;
    auto value = [&](std::size_t& i) -> const std::string& { return option_value(args, i, "fulgur-shot"); };
    for (std::size_t i = 0; i < args.size(); ++i) {
        const std::string& s = args[i];
        if (s == "--help" || s == "-h") {
            a.help = true;
            return a;
        } else if (s == "--fgb") {
            a.fgb = value(i);
        } else if (s == "--seed") {
            a.seed = parse_number<std::uint64_t>(value(i), "--seed");
            have_seed = true;
        } else if (s == "--time") {
            std::string v = value(i);
            if (!v.empty() && v[0] == '+') {
                a.time_after_return_stroke = true;
                v.erase(0, 1);
            }
            a.time = parse_number<double>(v, "--time");
            if (!std::isfinite(a.time) || a.time < 0.0)
                throw core::Error("fulgur-shot", "--time must be finite and >= 0");
            have_time = true;
        } else if (s == "--repeat") {
            a.repeat = parse_number<int>(value(i), "--repeat");
            if (a.repeat < 1 || a.repeat > 1000) throw core::Error("fulgur-shot", "--repeat must be in 1..1000");
        } else if (s == "--exposure") {
            a.exposure_ev = parse_number<double>(value(i), "--exposure");
            if (!(a.exposure_ev >= -20.0 && a.exposure_ev <= 20.0))
                throw core::Error("fulgur-shot", "--exposure must be in -20..20 stops");
        } else if (s == "--size") {
            const std::string& v = value(i);
            auto x = v.find('x');
            if (x == std::string::npos) throw core::Error("fulgur-shot", "--size must be WxH, got '" + v + "'");
            a.width = parse_number<int>(v.substr(0, x), "--size width");
            a.height = parse_number<int>(v.substr(x + 1), "--size height");
            if (a.width < 1 || a.height < 1 || a.width > 8192 || a.height > 8192)
                throw core::Error("fulgur-shot", "--size: each side must be in 1..8192, got '" + v + "'");
            have_size = true;
        } else if (s == "--reference") {
            a.reference = value(i);
            if (a.reference->extension() != ".png")
                throw core::Error("fulgur-shot",
                                  "--reference must name a .png file, got '" + a.reference->string() + "'");
        } else if (s == "-o" || s == "--output") {
            a.output = value(i);
            have_out = true;
        } else if (!s.empty() && s[0] == '-') {
            throw core::Error("fulgur-shot", "unknown option '" + s + "' (see --help)");
        } else if (a.scene.empty()) {
            a.scene = s;
        } else {
            throw core::Error("fulgur-shot", "more than one scene given ('" + a.scene.string() + "', '" + s + "')");
        }
    }
    if (a.scene.empty()) throw core::Error("fulgur-shot", "no SCENE.json given (see --help)");
    if (!have_seed) throw core::Error("fulgur-shot", "--seed is required");
    if (!have_time) throw core::Error("fulgur-shot", "--time is required");
    if (!have_size) throw core::Error("fulgur-shot", "--size is required");
    if (!have_out) throw core::Error("fulgur-shot", "-o is required");
    if (a.reference && std::filesystem::absolute(*a.reference) == std::filesystem::absolute(a.output))
        throw core::Error("fulgur-shot", "--reference and -o name the same file");
    return a;
}

}  // namespace fulgur::app
