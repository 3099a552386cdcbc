// Camera images to gray for the stages (common/stages/image_gray): what is
// refused and why, and that each encoding gives the same gray pixels.
#include <gtest/gtest.h>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "stages/image_gray.hpp"

using namespace vslam;

namespace {

config::CameraConfig camera(int width, int height) {
  config::CameraConfig c;
  c.name = "forward";
  c.width = width;
  c.height = height;
  return c;
}

// A 6x4 gray ramp, stored with a row stride of 8 (2 bytes of padding per row).
vslam::image_t rampGray8() {
  vslam::image_t m{};
  m.width = 6;
  m.height = 4;
  m.encoding = vslam::image_t::ENCODING_GRAY8;
  m.row_stride = 8;
  m.data.assign(static_cast<size_t>(m.row_stride * m.height), 0xEE);  // padding stays 0xEE
  for (int r = 0; r < m.height; ++r)
    for (int c = 0; c < m.width; ++c) m.data[static_cast<size_t>(r * 8 + c)] = uint8_t(10 * r + c);
  m.data_size = static_cast<int32_t>(m.data.size());
  return m;
}

}  // namespace

TEST(ImageGray, ChecksNameWhatIsWrong) {
  const vslam::image_t ok = rampGray8();
  EXPECT_FALSE(stages::checkImage(camera(6, 4), ok));

  const auto size = stages::checkImage(camera(320, 240), ok);
  ASSERT_TRUE(size);
  EXPECT_NE(size->find("image 6x4, but camera 'forward' is calibrated for 320x240"),
            std::string::npos)
      << *size;

  vslam::image_t short_data = ok;
  short_data.data.resize(short_data.data.size() - 1);
  const auto data = stages::checkImage(camera(6, 4), short_data);
  ASSERT_TRUE(data);
  EXPECT_NE(data->find("shorter than height x row_stride"), std::string::npos);

  vslam::image_t narrow_stride = ok;
  narrow_stride.row_stride = 5;  // less than the width
  EXPECT_TRUE(stages::checkImage(camera(6, 4), narrow_stride));

  vslam::image_t unknown = ok;
  unknown.encoding = 42;
  const auto encoding = stages::checkImage(camera(6, 4), unknown);
  ASSERT_TRUE(encoding);
  EXPECT_NE(encoding->find("unknown encoding 42"), std::string::npos);
}

TEST(ImageGray, EveryEncodingGivesTheSameGrayPixels) {
  const vslam::image_t gray8 = rampGray8();
  cv::Mat expected;
  ASSERT_FALSE(stages::imageToGray(gray8, &expected));
  ASSERT_EQ(expected.cols, 6);
  ASSERT_EQ(expected.rows, 4);
  for (int r = 0; r < 4; ++r)
    for (int c = 0; c < 6; ++c) EXPECT_EQ(expected.at<uint8_t>(r, c), 10 * r + c);  // no padding

  // BGR with equal channels converts to the same gray.
  vslam::image_t bgr8 = gray8;
  bgr8.encoding = vslam::image_t::ENCODING_BGR8;
  bgr8.row_stride = 18;
  bgr8.data.assign(18 * 4, 0);
  for (int r = 0; r < 4; ++r)
    for (int c = 0; c < 6; ++c)
      for (int k = 0; k < 3; ++k)
        bgr8.data[static_cast<size_t>(r * 18 + 3 * c + k)] = uint8_t(10 * r + c);
  cv::Mat from_bgr;
  ASSERT_FALSE(stages::checkImage(camera(6, 4), bgr8));
  ASSERT_FALSE(stages::imageToGray(bgr8, &from_bgr));
  EXPECT_EQ(cv::norm(from_bgr, expected, cv::NORM_INF), 0.0);

  // Lossless PNG bytes are not JPEG, but imdecode reads them: the decode path
  // and its size check are what is tested here.
  vslam::image_t jpeg = gray8;
  jpeg.encoding = vslam::image_t::ENCODING_JPEG;
  cv::imencode(".png", expected, jpeg.data);
  cv::Mat decoded;
  ASSERT_FALSE(stages::imageToGray(jpeg, &decoded));
  EXPECT_EQ(cv::norm(decoded, expected, cv::NORM_INF), 0.0);

  jpeg.width = 7;  // announced size differs from the pixels
  const auto wrong = stages::imageToGray(jpeg, &decoded);
  ASSERT_TRUE(wrong);
  EXPECT_NE(wrong->find("does not decode to the announced size"), std::string::npos);
  jpeg.data = {1, 2, 3};  // not an image
  jpeg.width = 6;
  EXPECT_TRUE(stages::imageToGray(jpeg, &decoded));
}
