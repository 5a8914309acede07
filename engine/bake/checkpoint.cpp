// The serialized results of per-light jobs and the checkpoint of a bake (detail/checkpoint.h,
// docs/distributed.md).
#include "bake/detail/checkpoint.h"

#include <zlib.h>

#include <algorithm>
#include <bit>
#include <cinttypes>
#include <cstdio>
#include <cstring>
#include <optional>

namespace fulgur::bake {

namespace {

// Little-endian bytes (the .fgb's convention; the build targets little-endian machines).
static_assert(std::endian::native == std::endian::little, "the serialized results are little-endian");

struct Out {
    std::vector<std::uint8_t> bytes;
    template <class T>
    void put(T v) {
        const auto* p = reinterpret_cast<const std::uint8_t*>(&v);
        bytes.insert(bytes.end(), p, p + sizeof v);
    }
};

struct In {
    std::span<const std::uint8_t> bytes;
    std::size_t at = 0;
    const std::string& where;
    void need(std::size_t n, const char* what) const {
        if (bytes.size() - at < n)
            throw core::Error(where + " (byte " + std::to_string(at) + ")",
                              std::string("truncated: ") + what + " needs " + std::to_string(n) + " bytes, " +
                                  std::to_string(bytes.size() - at) + " left");
    }
    template <class T>
    T get(const char* what) {
        need(sizeof(T), what);
        T v;
        std::memcpy(&v, bytes.data() + at, sizeof v);
        at += sizeof v;
        return v;
    }
};

std::uint32_t crc32_of(std::span<const std::uint8_t> bytes) noexcept {
    uLong crc = ::crc32(0L, Z_NULL, 0);
    for (std::size_t at = 0; at < bytes.size();) {  // zlib takes uInt lengths
        const uInt n = uInt(std::min<std::size_t>(bytes.size() - at, std::size_t(1) << 30));
        crc = ::crc32(crc, bytes.data() + at, n);
        at += n;
    }
    return std::uint32_t(crc);
}

// Bytes of one record before its block: light, crc, block size, 6 doubles, coefficients,
// iterations, converged.
constexpr std::size_t kRecordBytes = 4 + 4 + 8 + 6 * 8 + 8 + 4 + 4;

}  // namespace

std::vector<std::uint8_t> encode_results(std::span<const LightResult> results, bool with_blocks) {
    Out o;
    o.bytes.reserve(results.size() * kRecordBytes);
    for (const LightResult& r : results) {
        o.put(r.block.light);
        o.put(r.block.crc);
        o.put(std::uint64_t(r.block.bytes.size()));
        for (double v : {r.seconds_single, r.seconds_multiple, r.seconds_compress, r.ref2, r.err2, r.dropped_fraction})
            o.put(v);
        o.put(r.coefficients);
        o.put(r.iterations);
        o.put(std::uint32_t(r.converged ? 1 : 0));
        if (with_blocks) o.bytes.insert(o.bytes.end(), r.block.bytes.begin(), r.block.bytes.end());
    }
    return std::move(o.bytes);
}

std::vector<LightResult> decode_results(std::span<const std::uint8_t> bytes, bool with_blocks, std::uint32_t begin,
                                        std::uint32_t end, const std::string& where) {
    FULGUR_ASSERT(begin <= end, "decode_results: empty range");
    In in{bytes, 0, where};
    std::vector<LightResult> out;
    out.reserve(std::min<std::size_t>(end - begin, bytes.size() / kRecordBytes));
    for (std::uint32_t l = begin; l < end; ++l) {
        const std::size_t at = in.at;
        LightResult r;
        r.block.light = in.get<std::uint32_t>("light");
        if (r.block.light != l)
            throw core::Error(where + " (byte " + std::to_string(at) + ")",
                              "record of light " + std::to_string(r.block.light) + ", expected light " +
                                  std::to_string(l) + " (records follow the range " + std::to_string(begin) + ".." +
                                  std::to_string(end) + ")");
        r.block.crc = in.get<std::uint32_t>("block crc");
        const std::uint64_t size = in.get<std::uint64_t>("block size");
        r.seconds_single = in.get<double>("seconds");
        r.seconds_multiple = in.get<double>("seconds");
        r.seconds_compress = in.get<double>("seconds");
        r.ref2 = in.get<double>("norm");
        r.err2 = in.get<double>("error");
        r.dropped_fraction = in.get<double>("dropped fraction");
        r.coefficients = in.get<std::uint64_t>("coefficients");
        r.iterations = in.get<std::int32_t>("iterations");
        r.converged = in.get<std::uint32_t>("converged") != 0;
        if (with_blocks) {
            if (size > bytes.size() - in.at)
                throw core::Error(where + " (byte " + std::to_string(in.at) + ")",
                                  "truncated: light " + std::to_string(l) + "'s block has " + std::to_string(size) +
                                      " bytes, " + std::to_string(bytes.size() - in.at) + " left");
            r.block.bytes.assign(bytes.begin() + std::ptrdiff_t(in.at), bytes.begin() + std::ptrdiff_t(in.at + size));
            if (crc32_of(r.block.bytes) != r.block.crc)
                throw core::Error(where + " (byte " + std::to_string(in.at) + ")",
                                  "light " + std::to_string(l) + "'s block does not match its CRC-32");
            in.at += std::size_t(size);
        }
        // Without blocks the figures name their block by its CRC (the checkpoint checks it
        // against the .fgb's); the size is not kept.
        out.push_back(std::move(r));
    }
    if (in.at != bytes.size())
        throw core::Error(where + " (byte " + std::to_string(in.at) + ")",
                          std::to_string(bytes.size() - in.at) + " bytes after the last record");
    return out;
}

// ---------------------------------------------------------------------------------------

namespace detail {

namespace {

namespace fs = std::filesystem;

constexpr char kFiguresMagic[8] = {'F', 'U', 'L', 'G', 'C', 'K', 'P', 'T'};
constexpr std::uint32_t kCheckpointVersion = 1;
// magic, version, reserved, key hash, begin, end; the CRC-32 follows the records.
constexpr std::size_t kFiguresHeader = 8 + 4 + 4 + 8 + 4 + 4;
// Largest figures file read: 2^32 lights of records, far above any bake.
constexpr std::uint64_t kMaxFiguresBytes = std::uint64_t(1) << 40;

const char* const kNotUsed = " (the checkpoint was not used; remove its directory to bake from scratch)";

// "lights-00000012-00000016" -> its chunk; nothing when the name is not a chunk's.
std::optional<Chunk> parse_stem(const std::string& stem) {
    unsigned b = 0, e = 0;
    if (std::sscanf(stem.c_str(), "lights-%8u-%8u", &b, &e) != 2) return std::nullopt;
    const Chunk c{b, e};
    if (stem != Checkpoint::stem(c)) return std::nullopt;
    return c;
}

std::vector<std::uint8_t> figures_file(const basis::FgbMetadata& meta, Chunk c, std::span<const LightResult> r) {
    Out o;
    o.bytes.insert(o.bytes.end(), kFiguresMagic, kFiguresMagic + 8);
    o.put(kCheckpointVersion);
    o.put(std::uint32_t(0));
    o.put(meta.key.hash);
    o.put(c.begin);
    o.put(c.end);
    const std::vector<std::uint8_t> records = encode_results(r, false);
    o.bytes.insert(o.bytes.end(), records.begin(), records.end());
    o.put(crc32_of(o.bytes));
    return std::move(o.bytes);
}

std::vector<LightResult> read_figures(const fs::path& path, const basis::FgbMetadata& meta, Chunk c) {
    const std::string text = core::read_file(path, kMaxFiguresBytes, "checkpoint figures");
    const std::span<const std::uint8_t> bytes(reinterpret_cast<const std::uint8_t*>(text.data()), text.size());
    const std::string name = path.string();
    auto fail = [&](std::size_t at, const std::string& what) -> core::Error {
        return core::Error(name + " (byte " + std::to_string(at) + ")", what + kNotUsed);
    };
    if (bytes.size() < kFiguresHeader + 4)
        throw fail(0, "truncated: " + std::to_string(bytes.size()) + " bytes, the header alone is " +
                          std::to_string(kFiguresHeader + 4));
    if (std::memcmp(bytes.data(), kFiguresMagic, 8) != 0) throw fail(0, "magic: not a bake checkpoint's figures");
    std::uint32_t crc = 0;
    std::memcpy(&crc, bytes.data() + bytes.size() - 4, 4);
    if (crc32_of(bytes.first(bytes.size() - 4)) != crc)
        throw fail(bytes.size() - 4, "CRC-32 mismatch: the file is corrupt");
    In in{bytes.first(bytes.size() - 4), 8, name};
    const std::uint32_t version = in.get<std::uint32_t>("version");
    if (version != kCheckpointVersion)
        throw fail(8, "version " + std::to_string(version) + ", this build reads version " +
                          std::to_string(kCheckpointVersion));
    (void)in.get<std::uint32_t>("reserved");
    const std::uint64_t key = in.get<std::uint64_t>("scene key");
    if (key != meta.key.hash) {
        char msg[160];
        std::snprintf(msg, sizeof msg,
                      "scene key 0x%016" PRIx64 ", this bake's is 0x%016" PRIx64
                      ": a checkpoint of another scene or settings",
                      key, meta.key.hash);
        throw fail(16, msg);
    }
    const std::uint32_t b = in.get<std::uint32_t>("begin"), e = in.get<std::uint32_t>("end");
    if (b != c.begin || e != c.end)
        throw fail(24, "holds lights " + std::to_string(b) + ".." + std::to_string(e) + ", its name says " +
                           std::to_string(c.begin) + ".." + std::to_string(c.end));
    try {
        return decode_results(bytes.subspan(kFiguresHeader, bytes.size() - 4 - kFiguresHeader), false, b, e,
                              name + " (records from byte " + std::to_string(kFiguresHeader) + ")");
    } catch (const core::Error& err) {
        throw core::Error(err.where(), err.reason() + kNotUsed);
    }
}

}  // namespace

std::string Checkpoint::stem(Chunk c) {
    char buf[48];
    std::snprintf(buf, sizeof buf, "lights-%08u-%08u", unsigned(c.begin), unsigned(c.end));
    return buf;
}

Checkpoint::Checkpoint(std::filesystem::path dir, const Plan& plan) : dir_(std::move(dir)), meta_(plan.metadata) {
    std::error_code ec;
    if (fs::exists(dir_, ec) && !fs::is_directory(dir_, ec))
        throw core::Error(dir_.string(), "exists and is not a directory (a bake's checkpoint is one)");
    fs::create_directories(dir_, ec);
    if (ec) throw core::Error(dir_.string(), "cannot create the checkpoint directory: " + ec.message());

    std::vector<Chunk> blocks;
    std::vector<fs::path> figures_only;
    for (const fs::directory_entry& entry : fs::directory_iterator(dir_)) {
        const fs::path& p = entry.path();
        const std::string ext = p.extension().string();
        if (ext == ".tmp" || ext == ".lock") {  // a killed writer's temporary or lock
            fs::remove(p, ec);
            continue;
        }
        const std::optional<Chunk> c = parse_stem(p.stem().string());
        if (!c || (ext != ".fgb" && ext != ".stats") || !entry.is_regular_file(ec))
            throw core::Error(p.string(), std::string("not a file of a bake's checkpoint (lights-<begin>-<end>.fgb "
                                                      "or .stats)") +
                                              kNotUsed);
        if (ext == ".fgb")
            blocks.push_back(*c);
        else if (!fs::exists(dir_ / (stem(*c) + ".fgb"), ec))
            figures_only.push_back(p);
    }
    std::sort(blocks.begin(), blocks.end(), [](Chunk a, Chunk b) { return a.begin < b.begin; });
    const std::size_t n = plan.lights.count();
    for (std::size_t i = 0; i < blocks.size(); ++i) {
        const Chunk c = blocks[i];
        const fs::path fgb = dir_ / (stem(c) + ".fgb");
        if (!(c.begin < c.end && c.end <= n))
            throw core::Error(fgb.string(), "lights " + std::to_string(c.begin) + ".." + std::to_string(c.end) +
                                                " are not a range of this bake's " + std::to_string(n) + " lights" +
                                                kNotUsed);
        if (i > 0 && c.begin < blocks[i - 1].end)
            throw core::Error(fgb.string(), "its lights overlap those of " + stem(blocks[i - 1]) + ".fgb" + kNotUsed);
        const fs::path stats = dir_ / (stem(c) + ".stats");
        if (!fs::exists(stats, ec))
            throw core::Error(fgb.string(), std::string("has no figures file ") + stats.filename().string() + kNotUsed);
        Held h{c, {}};
        try {
            basis::FgbReader r(fgb);
            if (r.light_begin() != c.begin || r.light_end() != c.end)
                throw core::Error(fgb.string(), "its header holds lights " + std::to_string(r.light_begin()) + ".." +
                                                    std::to_string(r.light_end()) + ", its name says " +
                                                    std::to_string(c.begin) + ".." + std::to_string(c.end));
            r.check_metadata(meta_);
            h.figures = read_figures(stats, meta_, c);
            for (std::uint32_t l = c.begin; l < c.end; ++l)
                if (r.read_encoded(l).crc != h.figures[l - c.begin].block.crc)
                    throw core::Error(stats.string(), "the figures of light " + std::to_string(l) +
                                                          " name another block than the .fgb's");
        } catch (const core::Error& e) {
            const std::string reason = e.reason();
            if (reason.find(kNotUsed) != std::string::npos) throw;
            throw core::Error(e.where(), reason + kNotUsed);
        }
        lights_ += c.size();
        held_.push_back(std::move(h));
    }
    for (const fs::path& p : figures_only) fs::remove(p, ec);  // a kill between a chunk's two files
}

void Checkpoint::add(Chunk c, std::span<const LightResult> results) {
    FULGUR_ASSERT(results.size() == c.size(), "Checkpoint::add: one result per light of the chunk");
    core::write_file(dir_ / (stem(c) + ".stats"), [&] {
        const std::vector<std::uint8_t> b = figures_file(meta_, c, results);
        return std::string(b.begin(), b.end());
    }());
    basis::FgbWriter w(dir_ / (stem(c) + ".fgb"), meta_, c.begin, c.end);
    for (const LightResult& r : results) w.add(r.block);
    w.finish();
    Held h{c, std::vector<LightResult>(results.begin(), results.end())};
    for (LightResult& r : h.figures) r.block.bytes = {};
    std::lock_guard lock(mutex_);
    const auto at = std::lower_bound(held_.begin(), held_.end(), c.begin,
                                     [](const Held& x, std::uint32_t b) { return x.chunk.begin < b; });
    held_.insert(at, std::move(h));
    lights_ += c.size();
}

void Checkpoint::copy_blocks(basis::FgbWriter& writer) {
    std::lock_guard lock(mutex_);
    for (const Held& h : held_) {
        basis::FgbReader r(dir_ / (stem(h.chunk) + ".fgb"));
        for (std::uint32_t l = h.chunk.begin; l < h.chunk.end; ++l) writer.add(r.read_encoded(l));
    }
}

void Checkpoint::remove() {
    std::lock_guard lock(mutex_);
    std::error_code ec;
    fs::remove_all(dir_, ec);
    if (ec) throw core::Error(dir_.string(), "cannot remove the checkpoint directory: " + ec.message());
    held_.clear();
    lights_ = 0;
}

}  // namespace detail

}  // namespace fulgur::bake
