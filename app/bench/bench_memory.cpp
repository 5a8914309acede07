// The machine's memory bandwidth: the baseline other benchmarks report ratios against.
#include "bench/bench.h"

FULGUR_BENCH(memory, "STREAM-triad memory bandwidth on 1 and 2 threads (GB/s)") {
    for (int t = 1; t <= ctx.max_threads; ++t)
        ctx.emit("memory", {{"threads", t}, {"triad_GBps", fulgur::bench::measure_bandwidth(t)}});
}
