#include "study/study.h"

#include "core/core.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <iostream>
#include <sstream>

namespace fulgur::study {

namespace {

std::string esc(const std::string& s) {
    std::string o;
    for (char c : s) {
        if (c == '<')
            o += "&lt;";
        else if (c == '>')
            o += "&gt;";
        else if (c == '&')
            o += "&amp;";
        else
            o += c;
    }
    return o;
}

// "Nice" tick values covering [lo, hi] (linear).
std::vector<double> nice_ticks(double lo, double hi, int target = 6) {
    std::vector<double> t;
    if (!(hi > lo)) return {lo};
    const double raw = (hi - lo) / target;
    const double mag = std::pow(10.0, std::floor(std::log10(raw)));
    double step = mag;
    for (double m : {1.0, 2.0, 5.0, 10.0})
        if (m * mag >= raw) {
            step = m * mag;
            break;
        }
    for (double v = std::ceil(lo / step) * step; v <= hi + 1e-9 * step; v += step)
        t.push_back(std::fabs(v) < 1e-12 * step ? 0.0 : v);
    return t;
}
}  // namespace

std::vector<double> side_view(const transport::LightingMedium& m, std::size_t toward_camera,
                              const std::function<double(std::size_t, std::size_t)>& S) {
    const core::GridGeometry& g = m.density.geom;
    std::vector<double> img(std::size_t(g.dims.x) * std::size_t(g.dims.z), 0.0);
    const double h = g.voxel_size;
    for (int k = 0; k < g.dims.z; ++k)
        for (int i = 0; i < g.dims.x; ++i) {
            double tau = 0.0, sum = 0.0;
            for (int j = 0; j < g.dims.y; ++j) {
                const std::size_t c = g.index(i, j, k);
                const double st = m.sigma_t(c);
                sum += std::exp(-(tau + 0.5 * st * h)) * st * h * S(toward_camera, c);
                tau += st * h;
            }
            img[std::size_t(i) + std::size_t(g.dims.x) * std::size_t(k)] = sum;
        }
    return img;
}

std::size_t toward_side_camera(std::span<const glm::dvec3> dirs) {
    std::size_t best = 0;
    for (std::size_t m = 0; m < dirs.size(); ++m)
        if (dirs[m].y * -1.0 > dirs[best].y * -1.0) best = m;  // largest component along -y
    return best;
}

void Context::summary(const std::string& name, nlohmann::json j) const {
    if (!j.contains("study")) j["study"] = name;
    std::cout << j.dump() << std::endl;
}

std::filesystem::path Context::file(const std::string& name) const {
    std::error_code ec;
    std::filesystem::create_directories(output_dir, ec);
    if (ec) throw core::Error(output_dir.string(), "cannot create the output directory: " + ec.message());
    return output_dir / name;
}

Csv::Csv(const std::filesystem::path& path, const std::vector<std::string>& header)
    : path_(path), columns_(header.size()) {
    for (std::size_t i = 0; i < header.size(); ++i) buffer_ += (i ? "," : "") + header[i];
    buffer_ += "\n";
}
Csv& Csv::operator<<(double v) {
    buffer_ += (first_in_row_ ? "" : ",") + core::format_number(v, 9);
    first_in_row_ = false;
    ++in_row_;
    return *this;
}
Csv& Csv::operator<<(const std::string& v) {
    // RFC 4180: a field holding a comma, a quote or a line break is quoted, quotes doubled.
    std::string field = v;
    if (field.find_first_of(",\"\n\r") != std::string::npos) {
        field = "\"";
        for (const char c : v) field += c == '"' ? std::string("\"\"") : std::string(1, c);
        field += "\"";
    }
    buffer_ += (first_in_row_ ? "" : ",") + field;
    first_in_row_ = false;
    ++in_row_;
    return *this;
}
void Csv::end_row() {
    FULGUR_ASSERT(in_row_ == columns_, "CSV row has the wrong number of columns");
    buffer_ += "\n";
    first_in_row_ = true;
    in_row_ = 0;
}
void Csv::flush() { core::write_file(path_, buffer_); }
Csv::~Csv() {
    try {
        flush();
    } catch (const std::exception& e) {
        std::fprintf(stderr, "fulgur-study: %s\n", e.what());
    }
}

void write_svg_plot(const std::filesystem::path& path, const std::vector<Series>& series, const PlotOptions& opt) {
    static const char* palette[] = {"#1f77b4", "#d62728", "#2ca02c", "#ff7f0e",
                                    "#9467bd", "#8c564b", "#e377c2", "#17becf"};
    auto tx = [&](double v) { return opt.log_x ? std::log10(v) : v; };
    auto ty = [&](double v) { return opt.log_y ? std::log10(v) : v; };
    auto ok = [&](double x, double y) {
        return std::isfinite(x) && std::isfinite(y) && (!opt.log_x || x > 0) && (!opt.log_y || y > 0);
    };
    double x0 = 1e300, x1 = -1e300, y0 = 1e300, y1 = -1e300;
    for (const auto& s : series)
        for (std::size_t i = 0; i < std::min(s.x.size(), s.y.size()); ++i)
            if (ok(s.x[i], s.y[i])) {
                x0 = std::min(x0, tx(s.x[i]));
                x1 = std::max(x1, tx(s.x[i]));
                y0 = std::min(y0, ty(s.y[i]));
                y1 = std::max(y1, ty(s.y[i]));
            }
    for (const auto& v : opt.vlines) {
        x0 = std::min(x0, tx(v.first));
        x1 = std::max(x1, tx(v.first));
    }
    if (std::isfinite(opt.x_min)) x0 = tx(opt.x_min);
    if (std::isfinite(opt.x_max)) x1 = tx(opt.x_max);
    if (std::isfinite(opt.y_min)) y0 = ty(opt.y_min);
    if (std::isfinite(opt.y_max)) y1 = ty(opt.y_max);
    if (!(x1 > x0)) {
        x0 -= 1;
        x1 += 1;
    }
    if (!(y1 > y0)) {
        y0 -= 1;
        y1 += 1;
    }
    if (!opt.log_y && !std::isfinite(opt.y_min) && !std::isfinite(opt.y_max)) {
        const double pad = 0.05 * (y1 - y0);
        y0 -= pad;
        y1 += pad;
    }
    const double L = 80, R = 20, T = 40, B = 60;
    const double W = opt.width - L - R, H = opt.height - T - B;
    auto px = [&](double v) { return L + (tx(v) - x0) / (x1 - x0) * W; };
    auto py = [&](double v) { return T + H - (ty(v) - y0) / (y1 - y0) * H; };
    std::ostringstream o;
    o << "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"" << opt.width << "\" height=\"" << opt.height
      << "\" font-family=\"sans-serif\" font-size=\"12\">\n";
    o << "<rect width=\"100%\" height=\"100%\" fill=\"white\"/>\n";
    o << "<text x=\"" << opt.width / 2 << "\" y=\"22\" text-anchor=\"middle\" font-size=\"15\">" << esc(opt.title)
      << "</text>\n";
    o << "<defs><clipPath id=\"plot\"><rect x=\"" << L << "\" y=\"" << T << "\" width=\"" << W << "\" height=\"" << H
      << "\"/></clipPath></defs>\n";
    // Ticks and grid.
    auto axis_ticks = [&](double lo, double hi, bool log) {
        std::vector<double> t;
        if (log) {
            for (double e = std::floor(lo); e <= std::ceil(hi); e += 1.0)
                if (e >= lo - 1e-9 && e <= hi + 1e-9) t.push_back(std::pow(10.0, e));
            if (t.size() < 2) t = {std::pow(10.0, lo), std::pow(10.0, hi)};
        } else {
            t = nice_ticks(lo, hi);
        }
        return t;
    };
    for (double v : axis_ticks(x0, x1, opt.log_x)) {
        const double X = px(v);
        o << "<line x1=\"" << X << "\" y1=\"" << T << "\" x2=\"" << X << "\" y2=\"" << T + H
          << "\" stroke=\"#e4e4e4\"/>\n";
        o << "<text x=\"" << X << "\" y=\"" << T + H + 16 << "\" text-anchor=\"middle\">" << core::format_number(v, 9)
          << "</text>\n";
    }
    for (double v : axis_ticks(y0, y1, opt.log_y)) {
        const double Y = py(v);
        o << "<line x1=\"" << L << "\" y1=\"" << Y << "\" x2=\"" << L + W << "\" y2=\"" << Y
          << "\" stroke=\"#e4e4e4\"/>\n";
        o << "<text x=\"" << L - 6 << "\" y=\"" << Y + 4 << "\" text-anchor=\"end\">" << core::format_number(v, 9)
          << "</text>\n";
    }
    o << "<rect x=\"" << L << "\" y=\"" << T << "\" width=\"" << W << "\" height=\"" << H
      << "\" fill=\"none\" stroke=\"black\"/>\n";
    o << "<text x=\"" << L + W / 2 << "\" y=\"" << opt.height - 14 << "\" text-anchor=\"middle\">" << esc(opt.x_label)
      << "</text>\n";
    o << "<text transform=\"translate(18," << T + H / 2 << ") rotate(-90)\" text-anchor=\"middle\">" << esc(opt.y_label)
      << "</text>\n";
    for (const auto& v : opt.vlines) {
        const double X = px(v.first);
        o << "<line x1=\"" << X << "\" y1=\"" << T << "\" x2=\"" << X << "\" y2=\"" << T + H
          << "\" stroke=\"#777\" stroke-dasharray=\"5,4\"/>\n";
        o << "<text x=\"" << X + 4 << "\" y=\"" << T + 14 << "\" fill=\"#555\">" << esc(v.second) << "</text>\n";
    }
    for (const auto& h : opt.hlines) {
        const double Y = py(h.first);
        o << "<line x1=\"" << L << "\" y1=\"" << Y << "\" x2=\"" << L + W << "\" y2=\"" << Y
          << "\" stroke=\"#777\" stroke-dasharray=\"5,4\"/>\n";
        o << "<text x=\"" << L + 4 << "\" y=\"" << Y - 4 << "\" fill=\"#555\">" << esc(h.second) << "</text>\n";
    }
    // Series.
    for (std::size_t k = 0; k < series.size(); ++k) {
        const auto& s = series[k];
        const std::string col = s.color.empty() ? palette[k % 8] : s.color;
        std::ostringstream pts;
        for (std::size_t i = 0; i < std::min(s.x.size(), s.y.size()); ++i)
            if (ok(s.x[i], s.y[i])) pts << px(s.x[i]) << "," << py(s.y[i]) << " ";
        o << "<polyline clip-path=\"url(#plot)\" fill=\"none\" stroke=\"" << col << "\" stroke-width=\"1.8\""
          << (s.dashed ? " stroke-dasharray=\"7,4\"" : "") << " points=\"" << pts.str() << "\"/>\n";
        if (s.markers)
            for (std::size_t i = 0; i < std::min(s.x.size(), s.y.size()); ++i)
                if (ok(s.x[i], s.y[i]))
                    o << "<circle clip-path=\"url(#plot)\" cx=\"" << px(s.x[i]) << "\" cy=\"" << py(s.y[i])
                      << "\" r=\"3\" fill=\"" << col << "\"/>\n";
        const double ly = T + 16 + 18 * double(k);
        o << "<line x1=\"" << L + W - 230 << "\" y1=\"" << ly << "\" x2=\"" << L + W - 205 << "\" y2=\"" << ly
          << "\" stroke=\"" << col << "\" stroke-width=\"2.5\"" << (s.dashed ? " stroke-dasharray=\"7,4\"" : "")
          << "/>\n";
        o << "<text x=\"" << L + W - 200 << "\" y=\"" << ly + 4 << "\">" << esc(s.label) << "</text>\n";
    }
    o << "</svg>\n";
    core::write_file(path, o.str());
}

}  // namespace fulgur::study

int main(int argc, char** argv) {
    fulgur::study::Context ctx;
    return fulgur::app::registry_main(argc, argv,
                                      {"fulgur-study", "study",
                                       "Runs the named studies (all if none), writing CSV and SVG files into DIR\n"
                                       "(default ./study-output) and one JSON summary line per study on stdout.",
                                       16},
                                      ctx, [&ctx](CLI::App& app) {
                                          app.add_option("-o,--output", ctx.output_dir,
                                                         "output directory (default ./study-output)")
                                              ->type_name("DIR");
                                          app.add_option("--only", ctx.only,
                                                         "run only the named configurations, comma-separated; "
                                                         "\"P*\" names every one starting with P (frontier)")
                                              ->type_name("NAMES");
                                      });
}
