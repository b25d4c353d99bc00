// encode_chunk against the MCAP record layout, read back field by field; the ROS stamp's rounding and flooring;
// ChunkWriter's write errors (sticky: reported by every later call, nothing written after them).
#include <fcntl.h>
#include <gtest/gtest.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <memory>
#include <string>
#include <system_error>

#include "mcap_chunk_writer.h"

namespace cufund::logs {
namespace {

template <typename T>
T at(const std::vector<std::uint8_t>& b, std::size_t i) {
  T v;
  std::memcpy(&v, b.data() + i, sizeof v);
  return v;
}

TEST(StampSecNsec, RoundsHalfToEvenAndFloorsNegativeTimes) {
  std::int32_t sec;
  std::uint32_t nsec;
  stamp_sec_nsec(1.5, &sec, &nsec);
  EXPECT_EQ(sec, 1);
  EXPECT_EQ(nsec, 500000000u);
  stamp_sec_nsec(-0.25, &sec, &nsec);
  EXPECT_EQ(sec, -1);
  EXPECT_EQ(nsec, 750000000u);
  stamp_sec_nsec(2.5e-9, &sec, &nsec);  // 2.5 ns: half to even
  EXPECT_EQ(nsec, 2u);
  stamp_sec_nsec(std::nan(""), &sec, &nsec);
  EXPECT_EQ(sec, 0);
  EXPECT_EQ(nsec, 0u);
  stamp_sec_nsec(1e12, &sec, &nsec);  // clipped to int32
  EXPECT_EQ(sec, INT32_MAX);
}

TEST(RotateInverse, IsTheTransposedRotationOfTheNormalisedQuaternion) {
  // 90 deg about z, scaled by 2: R^T maps world x to body -y, world y to body x; z unchanged
  const double s = std::sqrt(0.5);
  const double q[4] = {2 * s, 0.0, 0.0, 2 * s}, v[3] = {1.0, 2.0, 3.0};
  double out[3];
  rotate_inverse(q, v, out);
  EXPECT_NEAR(out[0], 2.0, 1e-15);
  EXPECT_NEAR(out[1], -1.0, 1e-15);
  EXPECT_NEAR(out[2], 3.0, 1e-15);
  const double zero[4] = {0.0, 0.0, 0.0, 0.0}, bad[4] = {std::nan(""), 0.0, 0.0, 1.0};
  for (const double* qq : {zero, bad}) {
    rotate_inverse(qq, v, out);
    EXPECT_TRUE(std::isnan(out[0]) && std::isnan(out[1]) && std::isnan(out[2]));
  }
}

TEST(EncodeChunk, MessagesViewsAndIndexesAreWhereTheRecordsSay) {
  Block b;
  b.channel = 3;
  b.row_bytes = 12;  // a float64 time then 4 bytes
  const double times[3] = {0.2, 0.1, 0.1};
  for (int i = 0; i < 3; ++i) {
    std::uint8_t row[12];
    std::memcpy(row, &times[i], 8);
    std::memset(row + 8, 0x10 + i, 4);
    b.data.insert(b.data.end(), row, row + 12);
    b.log.push_back(static_cast<std::uint64_t>(times[i] * 1e9));
    b.publish.push_back(7);
    b.sequence.push_back(static_cast<std::uint32_t>(i));
  }
  auto views = std::make_shared<std::vector<ViewSpec>>(1);
  (*views)[0].channel = 4;
  (*views)[0].row_template.assign(16, 0xEE);
  (*views)[0].copies.push_back({8, 8, 4});
  (*views)[0].stamps.push_back({0, 4, 0});
  b.views = views;
  ChunkInfo info;
  const auto out = encode_chunk(b, Compression::kNone, 100, &info);
  ASSERT_EQ(out[0], 0x06);
  EXPECT_EQ(at<std::uint64_t>(out, 9), 100000000u);   // start
  EXPECT_EQ(at<std::uint64_t>(out, 17), 200000000u);  // end
  const std::uint64_t raw_size = at<std::uint64_t>(out, 25);
  EXPECT_EQ(raw_size, 3 * (31 + 12) + 3 * (31 + 16));
  EXPECT_EQ(at<std::uint32_t>(out, 37), 0u);  // no compression name
  const std::size_t records = 49;
  EXPECT_EQ(info.chunk_start, 100u);
  EXPECT_EQ(info.chunk_length, records + raw_size);
  ASSERT_EQ(info.message_index_offsets.size(), 2u);
  std::size_t index = info.chunk_length;
  for (const std::uint16_t channel : {3, 4}) {
    ASSERT_EQ(out[index], 0x07);
    EXPECT_EQ(at<std::uint16_t>(out, index + 9), channel);
    const std::uint64_t expected_log[3] = {100000000, 100000000, 200000000};
    for (int k = 0; k < 3; ++k) {  // by log time, ties in write order: messages 1, 2, 0
      const std::size_t e = index + 15 + 16 * k;
      EXPECT_EQ(at<std::uint64_t>(out, e), expected_log[k]);
      const std::size_t m = records + at<std::uint64_t>(out, e + 8);
      ASSERT_EQ(out[m], 0x05);
      EXPECT_EQ(at<std::uint16_t>(out, m + 9), channel);
      EXPECT_EQ(at<std::uint32_t>(out, m + 11), static_cast<std::uint32_t>((k + 1) % 3));
      EXPECT_EQ(at<std::uint64_t>(out, m + 15), expected_log[k]);
      if (channel == 4) {  // the view: stamp from the row's time, 4 copied bytes, the rest of the template
        EXPECT_EQ(at<std::int32_t>(out, m + 31), 0);
        EXPECT_EQ(at<std::uint32_t>(out, m + 35), k == 2 ? 200000000u : 100000000u);
        EXPECT_EQ(out[m + 31 + 8], 0x10 + (k + 1) % 3);
        EXPECT_EQ(out[m + 31 + 12], 0xEE);
      }
    }
    index += 15 + 48;
  }
  EXPECT_EQ(index, out.size());
  EXPECT_EQ(info.message_index_length, out.size() - info.chunk_length);
}

// A block of one 8-byte row.
Block one_row_block() {
  Block b;
  b.channel = 1;
  b.row_bytes = 8;
  b.data.assign(8, 0x5A);
  b.log.push_back(1);
  b.publish.push_back(1);
  b.sequence.push_back(0);
  return b;
}

// Whether f throws std::system_error with ENOSPC (the error /dev/full gives every write).
template <typename F>
bool throws_enospc(F&& f) {
  try {
    f();
  } catch (const std::system_error& e) {
    return e.code().value() == ENOSPC;
  }
  return false;
}

// The writer's descriptor first refers to /dev/full (every write fails with ENOSPC); after the first reported
// error it is pointed (dup2) at an empty regular file that would accept writes: the error must stay reported by
// every later write, chunk, finish and close, and the file must stay empty.
void check_write_error_is_sticky(bool background) {
  const int full = ::open("/dev/full", O_WRONLY);
  if (full < 0) GTEST_SKIP() << "needs /dev/full";
  char path[] = "/tmp/cufund_chunk_writer_XXXXXX";
  const int file = ::mkstemp(path);
  ASSERT_GE(file, 0);
  ::unlink(path);
  {
    ChunkWriter writer(full, Compression::kNone, background);
    if (background) {
      writer.write({1, 2, 3});  // handed to the thread; its error reaches finish()
      EXPECT_TRUE(throws_enospc([&] { writer.finish(); }));
    } else {
      EXPECT_TRUE(throws_enospc([&] { writer.write({1, 2, 3}); }));
    }
    EXPECT_EQ(writer.position(), 0u);
    ASSERT_EQ(::dup2(file, full), full);  // the "disk" recovers
    for (int k = 0; k < 3; ++k) {
      EXPECT_TRUE(throws_enospc([&] { writer.write({4, 5, 6}); })) << "write " << k;
      EXPECT_TRUE(throws_enospc([&] { writer.chunk(one_row_block()); })) << "chunk " << k;
      EXPECT_TRUE(throws_enospc([&] { writer.finish(); })) << "finish " << k;
    }
    EXPECT_TRUE(throws_enospc([&] { writer.close(); }));
    EXPECT_TRUE(throws_enospc([&] { writer.close(); }));     // and again
    EXPECT_TRUE(throws_enospc([&] { writer.write({7}); }));  // after close: still the write error
    EXPECT_TRUE(writer.chunks().empty());
    EXPECT_EQ(writer.position(), 0u);
  }  // the destructor reports nothing
  struct stat st {};
  ASSERT_EQ(::fstat(file, &st), 0);
  EXPECT_EQ(st.st_size, 0) << "bytes were written after a reported write error";
  ::close(file);
}

TEST(ChunkWriter, AWriteErrorStaysReportedAndNothingMoreIsWritten) { check_write_error_is_sticky(false); }

TEST(ChunkWriter, AWriteErrorOfTheThreadStaysReportedAndNothingMoreIsWritten) { check_write_error_is_sticky(true); }

// The same writer on a working file writes what it is given (the test above can tell an empty file from a full one).
TEST(ChunkWriter, WritesRecordsAndChunksInOrder) {
  char path[] = "/tmp/cufund_chunk_writer_XXXXXX";
  const int file = ::mkstemp(path);
  ASSERT_GE(file, 0);
  for (const bool background : {false, true}) {
    ASSERT_EQ(::ftruncate(file, 0), 0);
    ASSERT_EQ(::lseek(file, 0, SEEK_SET), 0);
    const int fd = ::dup(file);
    ChunkWriter writer(fd, Compression::kNone, background);
    writer.write({1, 2, 3});
    writer.chunk(one_row_block());
    writer.finish();
    ASSERT_EQ(writer.chunks().size(), 1u);
    EXPECT_EQ(writer.chunks()[0].chunk_start, 3u);
    const std::uint64_t end = writer.position();
    writer.close();
    struct stat st {};
    ASSERT_EQ(::fstat(file, &st), 0);
    EXPECT_EQ(static_cast<std::uint64_t>(st.st_size), end);
    EXPECT_GT(end, 3u);
  }
  ::close(file);
  ::unlink(path);
}

}  // namespace
}  // namespace cufund::logs
