// A PNG read back as 8-bit RGB, for the tests that check what a picture shows.
#pragma once

#include <gtest/gtest.h>
#include <png.h>

#include <cstdint>
#include <string>
#include <vector>

namespace mktree {

struct Image {
  uint32_t width = 0, height = 0;
  std::vector<uint8_t> rgb;
  const uint8_t* at(size_t x, size_t y) const { return &rgb[3 * (y * width + x)]; }
};

inline Image ReadPng(const std::string& path) {
  Image img;
  png_image p{};
  p.version = PNG_IMAGE_VERSION;
  EXPECT_TRUE(png_image_begin_read_from_file(&p, path.c_str())) << path << ": " << p.message;
  p.format = PNG_FORMAT_RGB;
  img.width = p.width;
  img.height = p.height;
  img.rgb.resize(PNG_IMAGE_SIZE(p));
  EXPECT_TRUE(png_image_finish_read(&p, nullptr, img.rgb.data(), 0, nullptr)) << p.message;
  return img;
}

}  // namespace mktree
