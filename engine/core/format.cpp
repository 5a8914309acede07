#include "core/core.h"

#include <cstdio>

namespace fulgur::core {

std::string format_seconds(double s) {
    char buf[48];
    if (!std::isfinite(s) || s < 0.0)
        std::snprintf(buf, sizeof buf, "?");
    else if (s >= 3600.0)
        std::snprintf(buf, sizeof buf, "%.1f h", s / 3600.0);
    else if (s >= 90.0)
        std::snprintf(buf, sizeof buf, "%.1f min", s / 60.0);
    else
        std::snprintf(buf, sizeof buf, "%.1f s", s);
    return buf;
}

std::string format_number(double v, int significant_digits) {
    char buf[64];
    std::snprintf(buf, sizeof buf, "%.*g", significant_digits, v);
    return buf;
}

std::string format_bytes(double b) {
    char buf[48];
    if (b >= 1e9)
        std::snprintf(buf, sizeof buf, "%.2f GB", b / 1e9);
    else if (b >= 1e6)
        std::snprintf(buf, sizeof buf, "%.1f MB", b / 1e6);
    else if (b >= 1e3)
        std::snprintf(buf, sizeof buf, "%.1f kB", b / 1e3);
    else
        std::snprintf(buf, sizeof buf, "%.0f B", b);
    return buf;
}

}  // namespace fulgur::core
