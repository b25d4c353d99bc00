// The file side of a run log (cufund.logs.McapLogger): turns blocks of one topic's encoded messages into MCAP
// Chunk + Message Index records (https://mcap.dev/spec), compresses them (lz4 frame or zstd) and writes them to
// a file, on a background thread that never touches Python: the simulation's thread only hands a block over.
#pragma once

#include <condition_variable>
#include <cstddef>
#include <cstdint>
#include <deque>
#include <exception>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <type_traits>
#include <utility>
#include <vector>

namespace cufund::logs {

// An allocator whose resize() leaves new bytes uninitialised: buffers that are written right after growing
// (rows, records, compressed data) would otherwise be zero-filled first.
template <typename T, typename A = std::allocator<T>>
class DefaultInitAllocator : public A {
  using Traits = std::allocator_traits<A>;

 public:
  template <typename U>
  struct rebind {
    using other = DefaultInitAllocator<U, typename Traits::template rebind_alloc<U>>;
  };
  using A::A;
  template <typename U>
  void construct(U* p) noexcept(std::is_nothrow_default_constructible<U>::value) {
    ::new (static_cast<void*>(p)) U;
  }
  template <typename U, typename... Args>
  void construct(U* p, Args&&... args) {
    Traits::construct(static_cast<A&>(*this), p, std::forward<Args>(args)...);
  }
};

using Bytes = std::vector<std::uint8_t, DefaultInitAllocator<std::uint8_t>>;

enum class Compression { kNone, kLz4, kZstd };

// "", "lz4" or "zstd" (std::invalid_argument otherwise).
Compression compression_from_name(const std::string& name);
const char* compression_name(Compression c);

// A companion channel whose messages are derived from a topic's fixed-size rows (a Foxglove pose or transform
// from an odometry row): each message is `row_template` with bytes copied from the source row, CDR stamps
// (int32 sec, uint32 nanosec) computed from a float64 time [s] in it, and vectors rotated into a body frame
// (an odometry's world velocity as nav_msgs/Odometry's twist in the child frame).
struct ViewSpec {
  struct Copy {
    std::size_t dst, src, bytes;
  };
  struct Stamp {
    std::size_t dst_sec, dst_nsec, src_t;
  };
  // dst (3 float64) = R(q)^T v: v (3 float64) at src_v, q (4 float64, [w, x, y, z], normalised here) at src_q;
  // NaN when q is zero or not finite.
  struct Rotate {
    std::size_t dst, src_v, src_q;
  };
  std::uint16_t channel = 0;
  std::vector<std::uint8_t> row_template;
  std::vector<Copy> copies;
  std::vector<Stamp> stamps;
  std::vector<Rotate> rotations;
};

// v rotated by the inverse of the rotation of quaternion q [w, x, y, z] (normalised first): R(q)^T v, the vector
// of the rotated frame whose world vector is v. NaN when |q| is 0 or not finite.
void rotate_inverse(const double q[4], const double v[3], double out[3]);

// The stamp of a ROS builtin_interfaces/Time from t [s]: t * 1e9 rounded half to even, non-finite -> 0,
// seconds floored and clipped to int32 (cufund.logs.cdr.stamp_sec_nsec, value for value).
void stamp_sec_nsec(double t, std::int32_t* sec, std::uint32_t* nsec);

// One topic's messages for one chunk, in write order.
struct Block {
  std::uint16_t channel = 0;
  std::size_t row_bytes = 0;        // > 0: every payload has this size; payload i is data[i * row_bytes ...]
  Bytes data;                       // the payloads, back to back
  std::vector<std::uint64_t> ends;  // row_bytes == 0: where each payload ends in data
  std::vector<std::uint64_t> log, publish;
  std::vector<std::uint32_t> sequence;
  std::shared_ptr<const std::vector<ViewSpec>> views;  // only with row_bytes > 0

  std::size_t size() const { return log.size(); }
};

// What the summary's Chunk Index record of one written chunk holds.
struct ChunkInfo {
  std::uint64_t start = 0, end = 0;  // log times [ns]
  std::uint64_t chunk_start = 0, chunk_length = 0, message_index_length = 0;
  std::uint64_t compressed_size = 0, uncompressed_size = 0;
  std::vector<std::pair<std::uint16_t, std::uint64_t>> message_index_offsets;
};

// Encodes one block as a Chunk record followed by its Message Index records (one per channel: the block's own,
// then its views'); records of a channel sorted by nothing, index entries by log time (stable). `position` is
// the file offset the chunk will start at; `info` is filled in.
std::vector<std::uint8_t> encode_chunk(const Block& block, Compression compression, std::uint64_t position,
                                       ChunkInfo* info);
// The same into `out`, with `scratch` for the uncompressed records: both reused from chunk to chunk (no fresh
// pages for every chunk).
void encode_chunk(const Block& block, Compression compression, std::uint64_t position, ChunkInfo* info, Bytes& out,
                  Bytes& scratch);

// Writes raw records and chunks to a file descriptor (owned, closed by close()) in submission order, on a
// background thread when `background` (at most `max_pending` jobs wait: a producer that outruns the disk
// waits). A write error (or any other of the thread) is sticky: it is rethrown by every later write, chunk,
// finish and close, and nothing more is written to the file.
class ChunkWriter {
 public:
  ChunkWriter(int fd, Compression compression, bool background, std::size_t max_pending = 8);
  ~ChunkWriter();  // finishes what was submitted (no summary) and closes the file
  ChunkWriter(const ChunkWriter&) = delete;
  ChunkWriter& operator=(const ChunkWriter&) = delete;

  void write(std::vector<std::uint8_t> records);
  void chunk(Block block);
  // Whether write/chunk would wait now (for a caller that releases a lock before waiting).
  bool full() const;
  // Waits until everything submitted is in the file.
  void finish();
  void close();

  // After finish(): the file position, the chunks written, messages per channel, first and last log time.
  std::uint64_t position() const { return position_; }
  const std::vector<ChunkInfo>& chunks() const { return chunks_; }
  const std::map<std::uint16_t, std::uint64_t>& message_counts() const { return counts_; }
  bool any_message() const { return any_message_; }
  std::uint64_t start_time() const { return start_; }
  std::uint64_t end_time() const { return end_; }

 private:
  struct Job {
    bool is_chunk = false;
    std::vector<std::uint8_t> records;
    Block block;
  };
  void submit(Job job);
  void run();
  void process(Job& job);
  void write_all(const std::uint8_t* data, std::size_t n);
  void rethrow();

  int fd_;
  Compression compression_;
  std::size_t max_pending_;
  std::uint64_t position_ = 0;
  std::vector<ChunkInfo> chunks_;
  std::map<std::uint16_t, std::uint64_t> counts_;
  bool any_message_ = false;
  std::uint64_t start_ = 0, end_ = 0;
  Bytes out_, scratch_;  // the writer's chunk buffers, reused

  mutable std::mutex mutex_;
  std::condition_variable wake_, space_;
  std::deque<Job> queue_;
  bool busy_ = false, stop_ = false;
  std::exception_ptr error_;
  std::thread* thread_ = nullptr;  // a pointer: a forked child leaks it instead of joining a thread it lacks
  long pid_;
};

}  // namespace cufund::logs
