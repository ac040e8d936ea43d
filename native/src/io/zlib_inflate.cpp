#include "io/zlib_inflate.hpp"

#include <zlib.h>

#include <algorithm>
#include <cstring>
#include <limits>

#include "io/io_detail.hpp"

namespace volrig::io_detail {

namespace {
constexpr std::size_t kInChunk = std::size_t(1) << 20;    // compressed bytes read per refill
constexpr std::size_t kOutChunk = std::size_t(1) << 30;   // largest avail_out handed to zlib at once
constexpr std::uint64_t kMaxRatio = 1032;                  // deflate's worst-case expansion
constexpr std::uint64_t kRatioSlack = 64 * 1024;
}  // namespace

void check_inflate_bound(const std::string& name, std::uint64_t expected, std::uint64_t compressed) {
    const std::uint64_t cap = std::numeric_limits<std::uint64_t>::max();
    const std::uint64_t most =
        compressed > (cap - kRatioSlack) / kMaxRatio ? cap : compressed * kMaxRatio + kRatioSlack;
    if (expected > most)
        fail(name, "header declares " + with_commas(expected) + " bytes but " + with_commas(compressed) +
                       " compressed bytes can inflate to at most " + with_commas(most));
}

// ---- Inflater ------------------------------------------------------------------------------------------------

Inflater::Inflater(const ByteSource& src, std::uint64_t offset, std::uint64_t length, std::string name,
                   std::uint64_t expected_total)
    : src_(src), name_(std::move(name)), expected_(expected_total), in_pos_(offset), in_end_(offset) {
    if (offset > src.size() || length > src.size() - offset)
        fail(name_, "compressed data of " + with_commas(length) + " bytes at offset " + with_commas(offset) +
                        " runs past the end of " + src.name() + " (" + with_commas(src.size()) + " bytes)");
    in_end_ = offset + length;
    in_.resize(static_cast<std::size_t>(std::min<std::uint64_t>(kInChunk, std::max<std::uint64_t>(length, 1))));
    z_ = new z_stream_s{};
    z_->next_in = in_.data();
    z_->avail_in = 0;
    if (inflateInit2(z_, 15 + 32) != Z_OK) {  // 15-bit window, zlib or gzip header auto-detected
        delete z_;
        z_ = nullptr;
        throw Error(name_ + ": cannot start zlib decompression");
    }
}

Inflater::~Inflater() {
    if (z_) {
        inflateEnd(z_);
        delete z_;
    }
}

// Moves unconsumed input to the front of the buffer and appends from the source. False when nothing was added.
bool Inflater::refill() {
    if (in_pos_ >= in_end_) return false;
    const std::size_t keep = z_->avail_in;
    if (keep > 0 && z_->next_in != in_.data()) std::memmove(in_.data(), z_->next_in, keep);
    const std::size_t room = in_.size() - keep;
    if (room == 0) return false;
    const auto n = static_cast<std::size_t>(std::min<std::uint64_t>(room, in_end_ - in_pos_));
    src_.read(in_pos_, in_.data() + keep, n);
    in_pos_ += n;
    z_->next_in = in_.data();
    z_->avail_in = static_cast<uInt>(keep + n);
    return true;
}

std::size_t Inflater::read_some(void* dst, std::size_t n) {
    auto* out = static_cast<std::uint8_t*>(dst);
    std::size_t done = 0;
    while (done < n && !ended_) {
        if (z_->avail_in == 0) refill();
        const std::size_t want = std::min(n - done, kOutChunk);
        z_->next_out = out + done;
        z_->avail_out = static_cast<uInt>(want);
        const uInt in_before = z_->avail_in;
        const int r = inflate(z_, Z_NO_FLUSH);
        const std::size_t got = want - z_->avail_out;
        done += got;
        produced_ += got;
        if (r == Z_STREAM_END) {
            // Another gzip member may follow (concatenated .gz files); anything else after the end is ignored.
            if (z_->avail_in < 2) refill();
            if (z_->avail_in >= 2 && z_->next_in[0] == 0x1f && z_->next_in[1] == 0x8b) {
                if (inflateReset(z_) != Z_OK) fail(name_, "cannot restart zlib decompression");
                continue;
            }
            ended_ = true;
            break;
        }
        if (r == Z_NEED_DICT) fail(name_, "corrupt compressed data (the stream needs a preset dictionary)");
        if (r == Z_DATA_ERROR || r == Z_STREAM_ERROR || r == Z_MEM_ERROR) {
            const char* msg = z_->msg ? z_->msg : (r == Z_MEM_ERROR ? "out of memory" : "invalid stream");
            fail(name_, std::string("corrupt compressed data (") + msg + ")");
        }
        // Z_OK or Z_BUF_ERROR: stop when no progress is possible because the input is exhausted.
        const bool progressed = got > 0 || z_->avail_in != in_before;
        if (!progressed && !refill()) {
            incomplete_ = true;
            ended_ = true;
            break;
        }
    }
    return done;
}

void Inflater::truncated() const {
    fail(name_, "compressed data is truncated: " + with_commas(produced_) + " of " + with_commas(expected_) +
                    " bytes");
}

void Inflater::read(void* dst, std::size_t n) {
    if (read_some(dst, n) < n) truncated();
}

void Inflater::skip(std::uint64_t n) {
    std::vector<std::uint8_t> scratch(static_cast<std::size_t>(std::min<std::uint64_t>(n, 1 << 16)));
    while (n > 0) {
        const auto step = static_cast<std::size_t>(std::min<std::uint64_t>(n, scratch.size()));
        read(scratch.data(), step);
        n -= step;
    }
}

void Inflater::finish() {
    std::uint8_t extra = 0;
    if (read_some(&extra, 1) > 0)
        fail(name_, "compressed data inflates to more data than the header declares (" + with_commas(expected_) +
                        " bytes)");
    if (incomplete_)
        fail(name_, "compressed data is truncated: the stream stops before its end marker after " +
                        with_commas(produced_) + " of " + with_commas(expected_) + " bytes");
}

void inflate_into(const ByteSource& src, std::uint64_t offset, std::uint64_t length, const std::string& name,
                  void* dst, std::size_t expected) {
    Inflater inf(src, offset, length, name, expected);
    inf.read(dst, expected);
    inf.finish();
}

// ---- Deflater ------------------------------------------------------------------------------------------------

Deflater::Deflater(FileWriter& out, bool gzip) : out_(out), buf_(std::size_t(1) << 20) {
    z_ = new z_stream_s{};
    if (deflateInit2(z_, Z_DEFAULT_COMPRESSION, Z_DEFLATED, gzip ? 15 + 16 : 15, 8, Z_DEFAULT_STRATEGY) != Z_OK) {
        delete z_;
        z_ = nullptr;
        throw Error("cannot start zlib compression");
    }
}

Deflater::~Deflater() {
    if (z_) {
        deflateEnd(z_);
        delete z_;
    }
}

void Deflater::pump(int flush) {
    for (;;) {
        z_->next_out = buf_.data();
        z_->avail_out = static_cast<uInt>(buf_.size());
        const int r = deflate(z_, flush);
        if (r == Z_STREAM_ERROR) throw Error("zlib compression failed");
        const std::size_t n = buf_.size() - z_->avail_out;
        if (n) out_.write(buf_.data(), n);
        written_ += n;
        if (flush == Z_FINISH ? r == Z_STREAM_END : (z_->avail_in == 0 && z_->avail_out != 0)) return;
    }
}

void Deflater::write(const void* data, std::size_t n) {
    auto* p = static_cast<const std::uint8_t*>(data);
    while (n > 0) {
        const std::size_t step = std::min(n, kOutChunk);
        z_->next_in = const_cast<Bytef*>(p);
        z_->avail_in = static_cast<uInt>(step);
        pump(Z_NO_FLUSH);
        p += step;
        n -= step;
    }
}

std::uint64_t Deflater::finish() {
    z_->next_in = nullptr;
    z_->avail_in = 0;
    pump(Z_FINISH);
    return written_;
}

}  // namespace volrig::io_detail
