// The parent's side of a contained OpenVDB read (detail/vdb_parent.h): forks the reading
// child, reads its records through a bounded buffer while watching its time and resident
// memory, and turns how it ended (a crash, a kill, an overrun, a malformed or incomplete
// reply) into core::Error naming the file. No OpenVDB here: the child alone runs it.
#include "cloud/detail/vdb_parent.h"

#include "core/core.h"

#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>

namespace fulgur::cloud::detail::vdb {

namespace {

// Time limit of one read: kBaseSeconds plus kSecondsPerMiB per MiB of file (OpenVDB reads and
// decompresses hundreds of MiB per second: a sound file never comes close).
constexpr double kBaseSeconds = 10.0, kSecondsPerMiB = 1.0;

const char* signal_name(int sig) {
    switch (sig) {
        case SIGABRT:
            return "SIGABRT";
        case SIGSEGV:
            return "SIGSEGV";
        case SIGBUS:
            return "SIGBUS";
        case SIGFPE:
            return "SIGFPE";
        case SIGILL:
            return "SIGILL";
        case SIGTRAP:
            return "SIGTRAP";
        case SIGSYS:
            return "SIGSYS";
        case SIGKILL:
            return "SIGKILL";
        case SIGXCPU:
            return "SIGXCPU";
        case SIGPIPE:
            return "SIGPIPE";
        case SIGTERM:
            return "SIGTERM";
        case SIGINT:
            return "SIGINT";
        default:
            return "signal";
    }
}

}  // namespace

std::uint64_t statm_bytes(pid_t pid, int field) {
    const std::string name = pid == 0 ? "/proc/self/statm" : "/proc/" + std::to_string(pid) + "/statm";
    const int fd = ::open(name.c_str(), O_RDONLY | O_CLOEXEC);
    if (fd < 0) return 0;
    char text[256];
    const ssize_t n = ::read(fd, text, sizeof text - 1);
    ::close(fd);
    if (n <= 0) return 0;
    text[n] = '\0';
    unsigned long long v[2] = {0, 0};
    if (std::sscanf(text, "%llu %llu", &v[0], &v[1]) != 2) return 0;
    return std::uint64_t(v[field]) * std::uint64_t(::sysconf(_SC_PAGESIZE));
}

Reader::Reader(const std::filesystem::path& path, std::uint64_t file_bytes, std::uint64_t budget, ChildBody body)
    : where_(path.string()),
      full_budget_(budget),
      budget_(descriptor_budget(file_bytes, budget)),
      seconds_(kBaseSeconds + kSecondsPerMiB * double(file_bytes) / double(1 << 20)) {
    initialize_openvdb();  // once, here: the children inherit the registry
    int fds[2];
    if (::pipe2(fds, O_CLOEXEC) != 0)
        throw core::Error(where_, std::string("cannot start the OpenVDB reader: pipe: ") + std::strerror(errno));
    // The child's resident size starts at most at the parent's (the pages it inherits).
    start_rss_ = statm_bytes(0, 1);
    rss_limit_ = add_saturated(start_rss_, add_saturated(budget_, kLibraryBytes));
    const pid_t parent = ::getpid();
    pid_ = ::fork();
    if (pid_ == 0) {
        ::close(fds[0]);
        child_main(fds[1], parent, budget, budget_, seconds_, body);
    }
    const int e = errno;
    ::close(fds[1]);
    if (pid_ < 0) {
        ::close(fds[0]);
        throw core::Error(where_, std::string("cannot start the OpenVDB reader: fork: ") + std::strerror(e));
    }
    fd_ = fds[0];
    deadline_ = std::chrono::steady_clock::now() + std::chrono::duration_cast<std::chrono::steady_clock::duration>(
                                                       std::chrono::duration<double>(seconds_));
}

void Reader::allow_dense(std::uint64_t bytes) {
    // 256 MiB a second: a quarter of what filling fresh pages runs at on the development machine.
    const double extra = double(bytes) / double(256u << 20);
    seconds_ += extra;
    deadline_ += std::chrono::duration_cast<std::chrono::steady_clock::duration>(std::chrono::duration<double>(extra));
}

Reader::~Reader() {
    if (pid_ > 0) {
        ::kill(pid_, SIGKILL);
        int status = 0;
        while (::waitpid(pid_, &status, 0) < 0 && errno == EINTR) {}
    }
    if (fd_ >= 0) ::close(fd_);
}

std::string Reader::get_string(std::size_t max) {
    const auto n = get<std::uint32_t>();
    if (n > max) malformed("a text of " + std::to_string(n) + " bytes");
    std::string s(n, '\0');
    get_bytes(s.data(), n);
    return s;
}

std::uint8_t Reader::get_tag() {
    const auto tag = get<std::uint8_t>();
    if (tag == kError) {
        const auto about = get<std::uint8_t>();
        const std::string grid = get_string(kMaxNameBytes);
        const std::string reason = cut(get_string(kMaxReasonBytes), kReasonCut);
        throw core::Error(about == 1   ? where_
                          : about == 2 ? file_ + ": grid " + in_quotes(cut(grid, kMaxNameBytes))
                                       : file_,
                          reason);
    }
    return tag;
}

void Reader::expect(std::uint8_t want, const char* what) {
    const std::uint8_t tag = get_tag();
    if (tag != want) malformed(std::string("record ") + std::to_string(int(tag)) + " where " + what + " belongs");
}

void Reader::malformed(const std::string& what) {
    throw core::Error(where_, "the OpenVDB reader sent a malformed reply (" + what + ") on this file: it is corrupt");
}

void Reader::finish() {
    if (pos_ != end_) malformed("bytes after the last record");
    try {
        refill_or_end();
    } catch (const Ended&) {
        if (!eof_) end();  // the deadline or the memory limit
        int status = 0;
        if (!reap(status)) return;  // its status is unknown, its reply complete
        if (WIFEXITED(status) && WEXITSTATUS(status) == 0) return;
        end(status);
    }
    malformed("bytes after the last record");
}

void Reader::refill() {
    try {
        refill_or_end();
    } catch (const Ended&) {
        end();
    }
}

void Reader::refill_or_end() {
    using clock = std::chrono::steady_clock;
    for (;;) {
        const auto now = clock::now();
        if (now >= deadline_) {
            timed_out_ = true;
            throw Ended{};
        }
        if (now >= next_rss_check_) {
            next_rss_check_ = now + std::chrono::milliseconds(20);
            if (statm_bytes(pid_, 1) > rss_limit_) {
                out_of_memory_ = true;
                throw Ended{};
            }
        }
        pollfd p{fd_, POLLIN, 0};
        const int r = ::poll(&p, 1, 20);
        if (r < 0 && errno != EINTR) throw Ended{};
        if (r <= 0) continue;
        const ssize_t n = ::read(fd_, buf_.data(), buf_.size());
        if (n < 0 && (errno == EINTR || errno == EAGAIN)) continue;
        if (n <= 0) {
            eof_ = true;
            throw Ended{};
        }
        pos_ = 0;
        end_ = std::size_t(n);
        return;
    }
}

// Waits for the child (killing it when it overran or does not exit by the deadline); false if
// its status is unknown (SIGCHLD ignored).
bool Reader::reap(int& status) {
    if (timed_out_ || out_of_memory_) ::kill(pid_, SIGKILL);
    for (;;) {
        const pid_t r = ::waitpid(pid_, &status, WNOHANG);
        if (r == pid_) {
            pid_ = -1;
            return true;
        }
        if (r < 0 && errno != EINTR) {
            pid_ = -1;
            return false;
        }
        if (std::chrono::steady_clock::now() >= deadline_ && !timed_out_) {
            timed_out_ = true;
            ::kill(pid_, SIGKILL);
        }
        ::usleep(1000);
    }
}

// The pipe ended before the reply did: why, as a refusal naming the file.
void Reader::end() {
    int status = 0;
    const bool known = reap(status);
    end(known ? status : -1);
}

void Reader::end(int status) {
    const std::string secs = core::format_number(seconds_, 3);
    const std::string budget = core::format_bytes(double(add_saturated(budget_, kLibraryBytes)));
    if (timed_out_ || (status >= 0 && WIFSIGNALED(status) && WTERMSIG(status) == SIGXCPU))
        throw core::Error(where_, "the OpenVDB reader took longer than " + secs +
                                      " s on this file (the limit for its size): it is corrupt");
    if (out_of_memory_ || (status >= 0 && WIFEXITED(status) && WEXITSTATUS(status) == kExitOutOfMemory))
        throw core::Error(where_, "the OpenVDB reader ran out of its memory budget of " + budget + " on this file (" +
                                      (descriptors_ && budget_ < full_budget_
                                           ? "for its descriptors: the library's share, 16 MiB and 4x the file"
                                           : "the load's memory limit") +
                                      "): it is corrupt, or too large");
    if (status >= 0 && WIFSIGNALED(status)) {
        const int sig = WTERMSIG(status);
        const std::string named = "signal " + std::to_string(sig) + ", " + signal_name(sig);
        if (sig == SIGKILL || sig == SIGTERM || sig == SIGINT)
            throw core::Error(where_, "the OpenVDB reader was killed (" + named + ") while reading this file");
        throw core::Error(where_, "the OpenVDB reader crashed (" + named + ") on this file: it is corrupt");
    }
    if (status >= 0 && WIFEXITED(status) && WEXITSTATUS(status) != 0)
        throw core::Error(where_, "the OpenVDB reader failed (exit status " + std::to_string(WEXITSTATUS(status)) +
                                      ") on this file: it is corrupt");
    throw core::Error(where_, "the OpenVDB reader ended without a complete reply on this file: it is corrupt");
}

std::vector<GridFacts> receive_facts(Reader& r) {
    r.expect(kFacts, "the descriptors");
    const auto n = r.get<std::uint32_t>();
    if (n > kMaxGrids) r.malformed(std::to_string(n) + " grids");
    std::vector<GridFacts> facts(n);
    for (GridFacts& F : facts) {
        F.name = r.get_string(kMaxNameBytes);
        F.value_type = r.get_string(kMaxNameBytes);
        F.map_type = r.get_string(kMaxNameBytes);
        const auto flags = r.get<std::uint8_t>();
        F.float_grid = flags & 1;
        F.linear = flags & 2;
        F.has_bbox_min = flags & 4;
        F.has_bbox_max = flags & 8;
        F.has_count = flags & 16;
        F.has_mem = flags & 32;
        r.get_bytes(F.bbox_min, sizeof F.bbox_min);
        r.get_bytes(F.bbox_max, sizeof F.bbox_max);
        F.count = r.get<std::int64_t>();
        F.mem = r.get<std::int64_t>();
        r.get_bytes(F.m, sizeof F.m);
    }
    return facts;
}

}  // namespace fulgur::cloud::detail::vdb
