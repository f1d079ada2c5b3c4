// io: SHA-256, JSON round trip, XDMF series serialisation, parallel HDF5 rows (1 and 2 ranks).
#include <gtest/gtest.h>
#include <mpi.h>

#include <cmath>
#include <filesystem>

#include "core/Mpi.hpp"
#include "core/Sha256.hpp"
#include "io/AtomicFile.hpp"
#include "io/Hdf5.hpp"
#include "io/Json.hpp"
#include "io/Xdmf.hpp"

namespace gw = grainwave;
namespace fs = std::filesystem;

TEST(Sha256, KnownVectors) {
  EXPECT_EQ(gw::sha256_hex(""), "e3b0c44298fc1c149afbf4c8996fb92427ae41e4649b934ca495991b7852b855");
  EXPECT_EQ(gw::sha256_hex("abc"),
            "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad");
  // Two blocks of padding (message of 56 bytes).
  EXPECT_EQ(gw::sha256_hex("abcdbcdecdefdefgefghfghighijhijkijkljklmklmnlmnomnopnopq"),
            "248d6a61d20638b8e5c026930c3e6039a33ce45964ff2167f6ecedd419db06c1");
}

TEST(Json, RoundTripKeepsOrderAndValues) {
  gw::io::Json j = gw::io::Json::object();
  j.set("b", 1.5).set("a", 3).set("s", "x\"y").set("n", gw::io::Json(gw::io::Json::Array{1, 2.5}));
  j["nested"].set("k", true);
  const auto back = gw::io::Json::parse(j.dump());
  EXPECT_EQ(back.dump(), j.dump());
  EXPECT_DOUBLE_EQ(back.find("b")->number(), 1.5);
  EXPECT_EQ(back.find("s")->text(), "x\"y");
  EXPECT_LT(j.dump().find("\"b\""), j.dump().find("\"a\""));
  EXPECT_THROW(gw::io::Json::parse("{\"a\": }"), std::runtime_error);
  gw::io::Json nan = gw::io::Json::object();
  nan.set("x", std::nan(""));
  EXPECT_EQ(nan.dump(), "{\n  \"x\": null\n}");
}

TEST(Xdmf, SeriesSerialisationRoundTrips) {
  gw::io::XdmfTimeSeries a("a.xmf"), b("b.xmf");
  a.add(0.1, "<Grid>\n1\n</Grid>\n");
  a.add(0.30000000000000004, "<Grid>\n2\n</Grid>\n");
  b.restore(a.serialise());
  EXPECT_EQ(b.serialise(), a.serialise());
  EXPECT_EQ(b.size(), 2u);
}

TEST(Hdf5, DistributedRowsRoundTripOnAnyRankCount) {
  const int rank = gw::mpi::rank(), size = gw::mpi::size();
  fs::path path = fs::temp_directory_path() / "grainwave_test_rows.h5";
  if (rank == 0) fs::remove(path);
  // Rank r contributes r + 2 rows of 3 components: row k of the file holds (k, 10k, 100k).
  const std::size_t rows = static_cast<std::size_t>(rank) + 2;
  const auto first = gw::mpi::exclusive_prefix_sum(static_cast<std::int64_t>(rows));
  std::vector<double> data;
  for (std::size_t i = 0; i < rows; ++i) {
    const double k = static_cast<double>(first) + static_cast<double>(i);
    data.insert(data.end(), {k, 10 * k, 100 * k});
  }
  {
    auto file = gw::io::Hdf5File::create(path);
    EXPECT_TRUE(fs::exists(gw::io::temporary_path(path)));
    EXPECT_FALSE(fs::exists(path));  // not under its final name until committed
    file.root().set_attribute("answer", std::int64_t{42});
    file.root().set_attribute("label", std::string("rows"));
    const auto total = file.root().write_rows("v", data.data(), rows, 3);
    EXPECT_EQ(total, static_cast<std::int64_t>(size * (size + 3) / 2));
    file.commit();
  }
  EXPECT_TRUE(fs::exists(path));
  EXPECT_FALSE(fs::exists(gw::io::temporary_path(path)));
  auto file = gw::io::Hdf5File::open_read(path, MPI_COMM_SELF);
  EXPECT_EQ(file.root().integer_attribute("answer"), 42);
  EXPECT_EQ(file.root().text_attribute("label"), "rows");
  const auto shape = file.root().shape("v");
  ASSERT_EQ(shape.size(), 2u);
  const auto all = file.root().read_rows_real("v", 0, shape[0]);
  for (std::size_t k = 0; k < shape[0]; ++k) {
    EXPECT_EQ(all[3 * k], static_cast<double>(k));
    EXPECT_EQ(all[3 * k + 2], 100.0 * static_cast<double>(k));
  }
  MPI_Barrier(MPI_COMM_WORLD);
}

TEST(AtomicFile, TextIsRenamedIntoPlace) {
  if (gw::mpi::rank() != 0) return;
  const fs::path p = fs::temp_directory_path() / "grainwave_atomic.txt";
  gw::io::write_text_atomically(p, "hello\n");
  EXPECT_TRUE(fs::exists(p));
  EXPECT_FALSE(fs::exists(gw::io::temporary_path(p)));
  EXPECT_EQ(fs::file_size(p), 6u);
}
