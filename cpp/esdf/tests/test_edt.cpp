#include "edt.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "brute_force.h"

namespace cufund::esdf {
namespace {

using test::brute_squared;
using test::Index;
using test::random_sites;

std::vector<double> run(const std::vector<std::uint8_t>& sites, const std::array<Index, 3>& n, EdtOptions opt) {
  std::vector<double> out(sites.size());
  EXPECT_EQ(euclidean_distance_transform(sites.data(), n, opt, out.data()), EdtStatus::kOk);
  return out;
}

TEST(Edt, IsotropicMatchesBruteForceExactly) {
  for (std::uint32_t seed = 0; seed < 6; ++seed) {
    const std::array<Index, 3> n{7 + seed, 9, 5 + 2 * seed};
    const auto sites = random_sites(n[0] * n[1] * n[2], seed % 2 ? 0.02 : 0.2, seed);
    const auto ref = brute_squared(sites, n, {1.0, 1.0, 1.0});
    const auto got = run(sites, n, EdtOptions{});
    for (std::size_t i = 0; i < got.size(); ++i) ASSERT_EQ(got[i], std::sqrt(ref[i])) << "voxel " << i;
  }
}

TEST(Edt, AnisotropicMatchesBruteForce) {
  for (std::uint32_t seed = 0; seed < 6; ++seed) {
    const std::array<Index, 3> n{11, 4 + seed, 13};
    const auto sites = random_sites(n[0] * n[1] * n[2], 0.05, 100 + seed);
    const std::array<double, 3> h{0.3, 1.7, 0.05 + 0.1 * seed};
    EdtOptions opt;
    opt.voxel_size = h;
    const auto ref = brute_squared(sites, n, h);
    const auto got = run(sites, n, opt);
    for (std::size_t i = 0; i < got.size(); ++i) ASSERT_NEAR(got[i], std::sqrt(ref[i]), 1e-12 * std::sqrt(ref[i]));
  }
}

TEST(Edt, TwoAndOneDimensional) {
  const std::array<Index, 3> n2{1, 23, 17}, n1{1, 1, 40};
  for (const auto& n : {n2, n1}) {
    const auto sites = random_sites(n[0] * n[1] * n[2], 0.1, 7);
    const auto ref = brute_squared(sites, n, {1.0, 2.0, 0.5});
    EdtOptions opt;
    opt.voxel_size = {1.0, 2.0, 0.5};
    const auto got = run(sites, n, opt);
    for (std::size_t i = 0; i < got.size(); ++i) ASSERT_NEAR(got[i], std::sqrt(ref[i]), 1e-12 * std::sqrt(ref[i]));
  }
}

TEST(Edt, SignedIsOutsideMinusInside) {
  const std::array<Index, 3> n{8, 10, 9};
  const auto sites = random_sites(n[0] * n[1] * n[2], 0.4, 3);
  std::vector<std::uint8_t> inverse(sites.size());
  for (std::size_t i = 0; i < sites.size(); ++i) inverse[i] = sites[i] ? 0 : 1;
  const auto out = brute_squared(sites, n, {1, 1, 1}), in = brute_squared(inverse, n, {1, 1, 1});
  EdtOptions opt;
  opt.signed_distance = true;
  const auto got = run(sites, n, opt);
  for (std::size_t i = 0; i < got.size(); ++i) {
    ASSERT_EQ(got[i], sites[i] ? -std::sqrt(in[i]) : std::sqrt(out[i]));
    ASSERT_EQ(got[i] < 0.0, sites[i] == 1);
  }
}

TEST(Edt, FloatAgreesWithDoubleAndThreadsDoNotMatter) {
  const std::array<Index, 3> n{40, 33, 21};
  const auto sites = random_sites(n[0] * n[1] * n[2], 0.01, 11);
  EdtOptions opt;
  opt.voxel_size = {0.1, 0.1, 0.2};
  opt.nthreads = 1;
  const auto one = run(sites, n, opt);
  opt.nthreads = 3;
  const auto three = run(sites, n, opt);
  std::vector<float> f(sites.size());
  ASSERT_EQ(euclidean_distance_transform(sites.data(), n, opt, f.data()), EdtStatus::kOk);
  for (std::size_t i = 0; i < one.size(); ++i) {
    ASSERT_EQ(one[i], three[i]);
    ASSERT_NEAR(f[i], one[i], 1e-6 * one[i]);
  }
}

TEST(Edt, NoSitesIsInfinityAndBadInputIsRejected) {
  const std::array<Index, 3> n{3, 4, 5};
  const std::vector<std::uint8_t> none(60, 0);
  for (double d : run(none, n, EdtOptions{})) EXPECT_EQ(d, std::numeric_limits<double>::infinity());
  std::vector<double> out(60);
  EdtOptions bad;
  bad.voxel_size = {1.0, 0.0, 1.0};
  EXPECT_EQ(euclidean_distance_transform(none.data(), n, bad, out.data()), EdtStatus::kBadVoxelSize);
  bad.voxel_size = {1.0, std::nan(""), 1.0};
  EXPECT_EQ(euclidean_distance_transform(none.data(), n, bad, out.data()), EdtStatus::kBadVoxelSize);
  EXPECT_EQ(euclidean_distance_transform(none.data(), {3, 0, 5}, EdtOptions{}, out.data()), EdtStatus::kBadShape);
}

}  // namespace
}  // namespace cufund::esdf
