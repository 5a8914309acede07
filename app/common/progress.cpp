#include "progress.h"

#include "core/core.h"

#include <unistd.h>

#include <cmath>
#include <memory>

namespace fulgur::app {

ProgressFn make_progress_printer(std::FILE* out, std::string label) {
    const bool tty = isatty(fileno(out)) != 0;
    struct State {
        double last_print = -1e300;
        int last_decile = -1;
    };
    auto st = std::make_shared<State>();
    return [out, tty, label = std::move(label), st](std::size_t done, std::size_t total, double seconds) {
        const double f = total ? double(done) / double(total) : 1.0;
        const double eta = done ? seconds * (1.0 - f) / f : NAN;
        if (tty) {
            if (done != total && seconds - st->last_print < 0.1) return;  // ~10 redraws per second
            st->last_print = seconds;
            constexpr int kWidth = 32;
            const int n = int(std::lround(f * kWidth));
            std::fprintf(out, "\r[%s%s] %5.1f%%  %zu/%zu %s  %s elapsed, ETA %s   ",
                         std::string(std::size_t(n), '#').c_str(), std::string(std::size_t(kWidth - n), '.').c_str(),
                         100.0 * f, done, total, label.c_str(), core::format_seconds(seconds).c_str(),
                         done == total ? "0 s" : core::format_seconds(eta).c_str());
            if (done == total) std::fprintf(out, "\n");
        } else {
            const int decile = int(f * 10.0);
            if (done != total && decile == st->last_decile && seconds - st->last_print < 10.0) return;
            st->last_decile = decile;
            st->last_print = seconds;
            std::fprintf(out, "%zu/%zu %s (%.0f%%), %s elapsed, ETA %s\n", done, total, label.c_str(), 100.0 * f,
                         core::format_seconds(seconds).c_str(),
                         done == total ? "0 s" : core::format_seconds(eta).c_str());
        }
        std::fflush(out);
    };
}

}  // namespace fulgur::app
