#pragma once
// Damage to a checkpoint.nc, as the probes of issue 10 did it: values
// rewritten through the NetCDF API (no checksum update), and bytes flipped in
// the stored data of a field.
#include <gtest/gtest.h>
#include <netcdf.h>

#include <algorithm>
#include <cstddef>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

#include "grid/Grid.hpp"

namespace ehlsim::testing {

/// Rewrites the global attribute `name` of a NetCDF file with one value.
template <class T>
void rewrite_attribute(const std::filesystem::path& path, const char* name, T value) {
  int id = -1;
  ASSERT_EQ(nc_open(path.c_str(), NC_WRITE, &id), NC_NOERR);
  ASSERT_EQ(nc_redef(id), NC_NOERR);
  if constexpr (std::is_same_v<T, double>) {
    ASSERT_EQ(nc_put_att_double(id, NC_GLOBAL, name, NC_DOUBLE, 1, &value), NC_NOERR);
  } else {
    ASSERT_EQ(nc_put_att_int(id, NC_GLOBAL, name, NC_INT, 1, &value), NC_NOERR);
  }
  ASSERT_EQ(nc_close(id), NC_NOERR);
}

/// Rewrites the global text attribute `name` of a NetCDF file.
inline void rewrite_text_attribute(const std::filesystem::path& path, const char* name,
                                   const std::string& text) {
  int id = -1;
  ASSERT_EQ(nc_open(path.c_str(), NC_WRITE, &id), NC_NOERR);
  ASSERT_EQ(nc_redef(id), NC_NOERR);
  ASSERT_EQ(nc_put_att_text(id, NC_GLOBAL, name, text.size(), text.c_str()), NC_NOERR);
  ASSERT_EQ(nc_close(id), NC_NOERR);
}

/// Removes the global attribute `name`.
inline void delete_attribute(const std::filesystem::path& path, const char* name) {
  int id = -1;
  ASSERT_EQ(nc_open(path.c_str(), NC_WRITE, &id), NC_NOERR);
  ASSERT_EQ(nc_redef(id), NC_NOERR);
  ASSERT_EQ(nc_del_att(id, NC_GLOBAL, name), NC_NOERR);
  ASSERT_EQ(nc_close(id), NC_NOERR);
}

/// Rewrites one value of the NetCDF variable `name` at `index`.
inline void rewrite_value(const std::filesystem::path& path, const char* name,
                          const std::vector<std::size_t>& index, double value) {
  int id = -1, var = -1;
  ASSERT_EQ(nc_open(path.c_str(), NC_WRITE, &id), NC_NOERR);
  ASSERT_EQ(nc_inq_varid(id, name, &var), NC_NOERR);
  ASSERT_EQ(nc_put_var1_double(id, var, index.data(), &value), NC_NOERR);
  ASSERT_EQ(nc_close(id), NC_NOERR);
}

/// Flips the low 4 bytes (mantissa bits, little-endian) of 4 consecutive
/// values of `field` where they are stored in the file: 16 bytes that leave
/// every value finite, positive and plausible, so only a checksum sees them.
inline void flip_16_bytes_of(const std::filesystem::path& path, const Field& field,
                             std::size_t first_value) {
  std::ifstream in(path, std::ios::binary);
  std::vector<char> bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const auto* data = reinterpret_cast<const char*>(field.data() + first_value);
  constexpr std::size_t kValues = 4;
  const auto at = std::search(bytes.begin(), bytes.end(), data, data + kValues * sizeof(double));
  ASSERT_NE(at, bytes.end()) << "the field's values are not stored as such in " << path;
  for (std::size_t v = 0; v < kValues; ++v) {
    for (std::size_t b = 0; b < 4; ++b) {
      auto& byte = *(at + static_cast<std::ptrdiff_t>(v * sizeof(double) + b));
      byte = static_cast<char>(~byte);
    }
  }
  std::ofstream(path, std::ios::binary | std::ios::trunc)
      .write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
}

}  // namespace ehlsim::testing
