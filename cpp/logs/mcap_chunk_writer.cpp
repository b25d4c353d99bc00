#include "mcap_chunk_writer.h"

#include <libdeflate.h>
#include <lz4frame.h>
#include <unistd.h>
#include <zstd.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <numeric>
#include <stdexcept>
#include <system_error>

static_assert(__BYTE_ORDER__ == __ORDER_LITTLE_ENDIAN__, "MCAP records are little-endian, as this host");

namespace cufund::logs {
namespace {

constexpr std::uint8_t kMessage = 0x05, kChunk = 0x06, kMessageIndex = 0x07;
constexpr std::size_t kMessageHeader = 2 + 4 + 8 + 8;  // channel, sequence, log time, publish time

template <typename T>
void put(Bytes& out, T v) {
  const auto* p = reinterpret_cast<const std::uint8_t*>(&v);
  out.insert(out.end(), p, p + sizeof(T));
}

template <typename T>
void put_at(std::uint8_t* out, T v) {
  std::memcpy(out, &v, sizeof(T));
}

// Appends one channel's Message records of the block; their offsets in the chunk go to `offsets`.
void append_messages(Bytes& raw, const Block& b, std::uint16_t channel, const ViewSpec* view,
                     std::vector<std::uint64_t>& offsets) {
  const std::size_t n = b.size();
  const std::size_t row = view ? view->row_template.size() : b.row_bytes;
  std::size_t at = raw.size();
  raw.resize(at + n * (1 + 8 + kMessageHeader) + (b.row_bytes ? n * row : b.data.size()));  // one resize
  offsets.resize(n);
  for (std::size_t i = 0; i < n; ++i) {
    const std::uint8_t* payload;
    std::size_t size;
    if (b.row_bytes) {
      payload = b.data.data() + i * b.row_bytes;
      size = row;
    } else {
      const std::uint64_t begin = i ? b.ends[i - 1] : 0;
      payload = b.data.data() + begin;
      size = b.ends[i] - begin;
    }
    offsets[i] = at;
    std::uint8_t* p = raw.data() + at;
    at += 1 + 8 + kMessageHeader + size;
    p[0] = kMessage;
    put_at<std::uint64_t>(p + 1, kMessageHeader + size);
    put_at<std::uint16_t>(p + 9, channel);
    put_at<std::uint32_t>(p + 11, b.sequence[i]);
    put_at<std::uint64_t>(p + 15, b.log[i]);
    put_at<std::uint64_t>(p + 23, b.publish[i]);
    std::uint8_t* dst = p + 31;
    if (view == nullptr) {
      std::memcpy(dst, payload, size);
      continue;
    }
    std::memcpy(dst, view->row_template.data(), size);
    for (const auto& c : view->copies) std::memcpy(dst + c.dst, payload + c.src, c.bytes);
    for (const auto& s : view->stamps) {
      double t;
      std::memcpy(&t, payload + s.src_t, sizeof t);
      std::int32_t sec;
      std::uint32_t nsec;
      stamp_sec_nsec(t, &sec, &nsec);
      put_at(dst + s.dst_sec, sec);
      put_at(dst + s.dst_nsec, nsec);
    }
    for (const auto& r : view->rotations) {
      double q[4], v[3], out[3];
      std::memcpy(q, payload + r.src_q, sizeof q);
      std::memcpy(v, payload + r.src_v, sizeof v);
      rotate_inverse(q, v, out);
      std::memcpy(dst + r.dst, out, sizeof out);
    }
  }
}

// Compresses src into out from `at` on (out grows to fit); the compressed size.
std::size_t compress_into(const std::uint8_t* src, std::size_t size, Compression c, Bytes& out, std::size_t at) {
  if (c == Compression::kLz4) {
    LZ4F_preferences_t prefs{};
    prefs.frameInfo.contentSize = size;
    out.resize(at + LZ4F_compressFrameBound(size, &prefs));
    const std::size_t n = LZ4F_compressFrame(out.data() + at, out.size() - at, src, size, &prefs);
    if (LZ4F_isError(n)) throw std::runtime_error(std::string("lz4 compression failed: ") + LZ4F_getErrorName(n));
    return n;
  }
  out.resize(at + ZSTD_compressBound(size));
  const std::size_t n = ZSTD_compress(out.data() + at, out.size() - at, src, size, 1);
  if (ZSTD_isError(n)) throw std::runtime_error(std::string("zstd compression failed: ") + ZSTD_getErrorName(n));
  return n;
}

}  // namespace

Compression compression_from_name(const std::string& name) {
  if (name.empty()) return Compression::kNone;
  if (name == "lz4") return Compression::kLz4;
  if (name == "zstd") return Compression::kZstd;
  throw std::invalid_argument("compression must be '', 'lz4' or 'zstd', got '" + name + "'");
}

const char* compression_name(Compression c) {
  return c == Compression::kLz4 ? "lz4" : c == Compression::kZstd ? "zstd" : "";
}

void stamp_sec_nsec(double t, std::int32_t* sec, std::uint32_t* nsec) {
  const double r = std::nearbyint(t * 1e9);  // the default rounding mode: half to even, as numpy's round
  std::int64_t ns = 0;
  if (std::isfinite(r)) {
    ns = r >= 9.2e18    ? std::int64_t{9200000000000000000}
         : r <= -9.2e18 ? -std::int64_t{9200000000000000000}
                        : static_cast<std::int64_t>(r);
  }
  std::int64_t s = ns / 1000000000;
  if (ns % 1000000000 < 0) --s;  // floor
  *nsec = static_cast<std::uint32_t>(ns - s * 1000000000);
  *sec = static_cast<std::int32_t>(std::clamp<std::int64_t>(s, INT32_MIN, INT32_MAX));
}

void rotate_inverse(const double q[4], const double v[3], double out[3]) {
  const double n = std::sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
  if (!(n > 0.0) || !std::isfinite(n)) {
    out[0] = out[1] = out[2] = std::nan("");
    return;
  }
  // R^T v with the conjugate's vector part u = -q_xyz / n: t = 2 u x v, R^T v = v + w t + u x t
  const double w = q[0] / n, u[3] = {-q[1] / n, -q[2] / n, -q[3] / n};
  const double t[3] = {2.0 * (u[1] * v[2] - u[2] * v[1]), 2.0 * (u[2] * v[0] - u[0] * v[2]),
                       2.0 * (u[0] * v[1] - u[1] * v[0])};
  out[0] = v[0] + w * t[0] + (u[1] * t[2] - u[2] * t[1]);
  out[1] = v[1] + w * t[1] + (u[2] * t[0] - u[0] * t[2]);
  out[2] = v[2] + w * t[2] + (u[0] * t[1] - u[1] * t[0]);
}

std::vector<std::uint8_t> encode_chunk(const Block& block, Compression compression, std::uint64_t position,
                                       ChunkInfo* info) {
  Bytes out, scratch;
  encode_chunk(block, compression, position, info, out, scratch);
  return std::vector<std::uint8_t>(out.begin(), out.end());
}

void encode_chunk(const Block& b, Compression compression, std::uint64_t position, ChunkInfo* info, Bytes& out,
                  Bytes& scratch) {
  const std::size_t n = b.size();
  if (n == 0 || b.publish.size() != n || b.sequence.size() != n ||
      (b.row_bytes ? b.data.size() != n * b.row_bytes : b.ends.size() != n || b.ends.back() != b.data.size())) {
    throw std::invalid_argument("encode_chunk: an empty or inconsistent block");
  }
  std::vector<std::size_t> order(n);
  std::iota(order.begin(), order.end(), std::size_t{0});
  if (!std::is_sorted(b.log.begin(), b.log.end())) {
    std::stable_sort(order.begin(), order.end(), [&](std::size_t i, std::size_t j) { return b.log[i] < b.log[j]; });
  }
  const auto [lo, hi] = std::minmax_element(b.log.begin(), b.log.end());

  std::vector<const ViewSpec*> views{nullptr};
  std::vector<std::uint16_t> channels{b.channel};
  if (b.row_bytes && b.views) {
    for (const auto& v : *b.views) {
      views.push_back(&v);
      channels.push_back(v.channel);
    }
  }
  const std::string name = compression_name(compression);
  const std::size_t header = 1 + 8 + 8 * 3 + 4 + 4 + name.size() + 8;
  // the records go straight after the chunk's header when stored as they are, else into scratch (reused)
  Bytes& raw = compression == Compression::kNone ? out : scratch;
  out.clear();
  scratch.clear();
  if (compression == Compression::kNone) out.resize(header);
  const std::size_t raw_start = raw.size();
  std::vector<std::vector<std::uint64_t>> offsets(channels.size());
  for (std::size_t g = 0; g < channels.size(); ++g) {
    append_messages(raw, b, channels[g], views[g], offsets[g]);
    if (raw_start) {
      for (auto& o : offsets[g]) o -= raw_start;  // offsets count from the chunk's first record
    }
  }
  const std::size_t raw_size = raw.size() - raw_start;
  const std::uint32_t crc = libdeflate_crc32(0, raw.data() + raw_start, raw_size);  // zlib's CRC-32, PCLMUL-fast
  std::size_t records = raw_size;
  if (compression != Compression::kNone) {
    records = compress_into(scratch.data(), raw_size, compression, out, header);
    out.resize(header + records);
  }
  std::uint8_t* h = out.data();
  h[0] = kChunk;
  put_at<std::uint64_t>(h + 1, header - 9 + records);
  put_at<std::uint64_t>(h + 9, *lo);
  put_at<std::uint64_t>(h + 17, *hi);
  put_at<std::uint64_t>(h + 25, raw_size);
  put_at<std::uint32_t>(h + 33, crc);
  put_at<std::uint32_t>(h + 37, static_cast<std::uint32_t>(name.size()));
  std::memcpy(h + 41, name.data(), name.size());
  put_at<std::uint64_t>(h + 41 + name.size(), records);
  const std::uint64_t chunk_length = out.size();

  info->start = *lo;
  info->end = *hi;
  info->chunk_start = position;
  info->chunk_length = chunk_length;
  info->compressed_size = records;
  info->uncompressed_size = raw_size;
  info->message_index_offsets.clear();
  out.reserve(out.size() + channels.size() * (15 + 16 * n));
  for (std::size_t g = 0; g < channels.size(); ++g) {
    info->message_index_offsets.emplace_back(channels[g], position + out.size());
    out.push_back(kMessageIndex);
    put<std::uint64_t>(out, 2 + 4 + 16 * n);
    put<std::uint16_t>(out, channels[g]);
    put<std::uint32_t>(out, static_cast<std::uint32_t>(16 * n));
    for (const std::size_t k : order) {
      put<std::uint64_t>(out, b.log[k]);
      put<std::uint64_t>(out, offsets[g][k]);
    }
  }
  info->message_index_length = out.size() - chunk_length;
}

ChunkWriter::ChunkWriter(int fd, Compression compression, bool background, std::size_t max_pending)
    : fd_(fd), compression_(compression), max_pending_(std::max<std::size_t>(max_pending, 1)), pid_(::getpid()) {
  const off_t at = ::lseek(fd_, 0, SEEK_CUR);
  position_ = at > 0 ? static_cast<std::uint64_t>(at) : 0;
  if (background) thread_ = new std::thread([this] { run(); });
}

ChunkWriter::~ChunkWriter() {
  try {
    close();
  } catch (...) {  // NOLINT(bugprone-empty-catch): a destructor reports nothing; close() is where errors go
  }
}

void ChunkWriter::write(std::vector<std::uint8_t> records) {
  Job job;
  job.records = std::move(records);
  submit(std::move(job));
}

void ChunkWriter::chunk(Block block) {
  Job job;
  job.is_chunk = true;
  job.block = std::move(block);
  submit(std::move(job));
}

bool ChunkWriter::full() const {
  if (::getpid() != pid_) return false;  // a forked child: submit() says so (and never takes the parent's lock)
  std::lock_guard<std::mutex> lock(mutex_);
  return thread_ != nullptr && queue_.size() >= max_pending_;
}

void ChunkWriter::submit(Job job) {
  if (::getpid() != pid_) {
    throw std::logic_error("an McapLogger cannot write from a forked child process; open one there");
  }
  rethrow();  // a write error stays reported: nothing is written after it (later offsets would be wrong)
  if (fd_ < 0) throw std::logic_error("the log is closed");
  if (thread_ == nullptr) {
    try {
      process(job);
    } catch (...) {
      std::lock_guard<std::mutex> lock(mutex_);
      error_ = std::current_exception();
      throw;
    }
    return;
  }
  std::unique_lock<std::mutex> lock(mutex_);
  space_.wait(lock, [this] { return queue_.size() < max_pending_ || error_; });
  if (error_) {
    lock.unlock();
    rethrow();
  }
  queue_.push_back(std::move(job));
  wake_.notify_one();
}

void ChunkWriter::run() {
  std::unique_lock<std::mutex> lock(mutex_);
  for (;;) {
    wake_.wait(lock, [this] { return stop_ || !queue_.empty(); });
    if (queue_.empty()) return;  // stop_ and nothing left
    Job job = std::move(queue_.front());
    queue_.pop_front();
    busy_ = true;
    const bool failed = error_ != nullptr;  // read under the lock
    space_.notify_all();
    lock.unlock();
    std::exception_ptr error;
    try {
      if (!failed) process(job);  // after an error, later jobs are dropped (their offsets would be wrong)
    } catch (...) {
      error = std::current_exception();
    }
    lock.lock();
    busy_ = false;
    if (error && !error_) error_ = error;
    space_.notify_all();
  }
}

void ChunkWriter::process(Job& job) {
  if (!job.is_chunk) {
    write_all(job.records.data(), job.records.size());
    return;
  }
  ChunkInfo info;
  encode_chunk(job.block, compression_, position_, &info, out_, scratch_);
  write_all(out_.data(), out_.size());
  const Block& b = job.block;
  counts_[b.channel] += b.size();
  if (b.views) {
    for (const auto& v : *b.views) counts_[v.channel] += b.size();
  }
  start_ = any_message_ ? std::min(start_, info.start) : info.start;
  end_ = any_message_ ? std::max(end_, info.end) : info.end;
  any_message_ = true;
  chunks_.push_back(std::move(info));
}

void ChunkWriter::write_all(const std::uint8_t* data, std::size_t n) {
  while (n > 0) {
    const ssize_t w = ::write(fd_, data, n);
    if (w < 0) {
      if (errno == EINTR) continue;
      throw std::system_error(errno, std::generic_category(), "writing the log failed");
    }
    data += w;
    n -= static_cast<std::size_t>(w);
    position_ += static_cast<std::uint64_t>(w);
  }
}

void ChunkWriter::rethrow() {
  std::exception_ptr error;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    error = error_;  // kept: every later call reports it again
  }
  if (error) std::rethrow_exception(error);
}

void ChunkWriter::finish() {
  if (thread_ != nullptr && ::getpid() == pid_) {
    std::unique_lock<std::mutex> lock(mutex_);
    space_.wait(lock, [this] { return (queue_.empty() && !busy_) || error_; });
  }
  rethrow();
}

void ChunkWriter::close() {
  if (thread_ != nullptr && ::getpid() == pid_) {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      stop_ = true;
    }
    wake_.notify_one();
    thread_->join();
    delete thread_;
  }
  thread_ = nullptr;  // in a forked child: leaked, never joined (the child has no such thread)
  if (fd_ >= 0) {
    ::close(fd_);
    fd_ = -1;
  }
  rethrow();
}

}  // namespace cufund::logs
