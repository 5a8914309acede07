// Progress display for long jobs (the bake): a bar with percentage and ETA redrawn in
// place on a terminal, plain lines (at most one per 10% or per 10 s) otherwise.
#pragma once

#include <cstddef>
#include <cstdio>
#include <functional>
#include <string>

namespace fulgur::app {

/// done, total, seconds elapsed (the signature of bake::Progress).
using ProgressFn = std::function<void(std::size_t, std::size_t, double)>;

/// A progress printer writing to `out`; `label` names the work ("lights").
/// Terminal detection: isatty(fileno(out)).
ProgressFn make_progress_printer(std::FILE* out, std::string label);

}  // namespace fulgur::app
