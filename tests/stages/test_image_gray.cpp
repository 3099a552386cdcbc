// Camera images to gray for the stages (common/stages/image_gray): what is
// refused and why (a JPEG from its header, before anything decodes it), and
// that each encoding gives the same gray pixels.
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

  // A JPEG of the right size decodes to what OpenCV's imdecode gives (lossy:
  // close to the ramp, not equal to it).
  vslam::image_t jpeg = gray8;
  jpeg.encoding = vslam::image_t::ENCODING_JPEG;
  jpeg.row_stride = 0;
  ASSERT_TRUE(cv::imencode(".jpg", expected, jpeg.data, {cv::IMWRITE_JPEG_QUALITY, 100}));
  ASSERT_FALSE(stages::checkImage(camera(6, 4), jpeg));
  cv::Mat decoded;
  ASSERT_FALSE(stages::imageToGray(jpeg, &decoded));
  EXPECT_EQ(cv::norm(decoded, cv::imdecode(jpeg.data, cv::IMREAD_GRAYSCALE), cv::NORM_INF), 0.0);
  EXPECT_LE(cv::norm(decoded, expected, cv::NORM_INF), 2.0);
}

namespace {

// A JPEG of a width x height noise image as an image_t of that size.
vslam::image_t jpegMessage(int width, int height, int type = CV_8UC1) {
  cv::Mat frame(height, width, type);
  cv::randu(frame, 0, 255);
  vslam::image_t m{};
  m.width = width;
  m.height = height;
  m.encoding = vslam::image_t::ENCODING_JPEG;
  cv::imencode(".jpg", frame, m.data);
  m.data_size = static_cast<int32_t>(m.data.size());
  return m;
}

// The offset of the first segment with marker `marker` (0xFF `marker`), or 0:
// a walk over the segments' lengths from the start-of-image marker.
size_t segmentOffset(const std::vector<uint8_t>& jpeg, uint8_t marker) {
  size_t at = 2;
  while (at + 4 <= jpeg.size() && jpeg[at] == 0xFF) {
    if (jpeg[at + 1] == marker) return at;
    at += 2 + (size_t{jpeg[at + 2]} << 8 | jpeg[at + 3]);
  }
  return 0;
}

}  // namespace

TEST(ImageGray, AJpegOfAnotherSizeIsRefusedNamingBoth) {
  const vslam::image_t m = jpegMessage(32, 24);
  stages::JpegHeader header;
  ASSERT_FALSE(stages::readJpegHeader(m.data.data(), m.data.size(), &header));
  EXPECT_EQ(header.width, 32);
  EXPECT_EQ(header.height, 24);
  EXPECT_EQ(header.components, 1);
  const vslam::image_t color = jpegMessage(8, 8, CV_8UC3);
  ASSERT_FALSE(stages::readJpegHeader(color.data.data(), color.data.size(), &header));
  EXPECT_EQ(header.components, 3);

  vslam::image_t other = jpegMessage(40, 30);
  other.width = 32;  // the message announces the camera's 32x24
  other.height = 24;
  const auto checked = stages::checkImage(camera(32, 24), other);
  ASSERT_TRUE(checked);
  EXPECT_NE(checked->find("JPEG header announces 40x30, but the message announces 32x24"),
            std::string::npos)
      << *checked;
  cv::Mat gray;
  const auto decoded = stages::imageToGray(other, &gray);
  ASSERT_TRUE(decoded);
  EXPECT_EQ(*decoded, *checked);
  EXPECT_TRUE(gray.empty()) << "refused before decoding";
}

TEST(ImageGray, AJpegAnnouncingAHugeImageIsRefusedFromItsHeader) {
  // A real header (tables, SOF, SOS) with its SOF patched to 60000x60000,
  // a few bytes of scan and the end-of-image marker: 60000x60000 would be
  // 3.6 GB of gray for OpenCV to allocate; the header is all that is read.
  const vslam::image_t real = jpegMessage(32, 24);
  const size_t sof = segmentOffset(real.data, 0xC0);  // baseline SOF0, as OpenCV writes
  const size_t sos = segmentOffset(real.data, 0xDA);
  ASSERT_GT(sof, 0u);
  ASSERT_GT(sos, sof);
  const size_t scan = sos + 2 + (size_t{real.data[sos + 2]} << 8 | real.data[sos + 3]);
  vslam::image_t hostile = real;
  hostile.data.assign(real.data.begin(), real.data.begin() + static_cast<long>(scan) + 8);
  hostile.data.push_back(0xFF);
  hostile.data.push_back(0xD9);
  // SOF: FF C0, length (2), precision (1), height (2), width (2), components.
  for (size_t at : {sof + 5, sof + 7}) {
    hostile.data[at] = 60000 >> 8;
    hostile.data[at + 1] = 60000 & 0xFF;
  }
  ASSERT_LT(hostile.data.size(), 1000u);

  stages::JpegHeader header;
  ASSERT_FALSE(stages::readJpegHeader(hostile.data.data(), hostile.data.size(), &header));
  EXPECT_EQ(header.width, 60000);
  EXPECT_EQ(header.height, 60000);
  const auto checked = stages::checkImage(camera(32, 24), hostile);
  ASSERT_TRUE(checked);
  EXPECT_NE(checked->find("JPEG header announces 60000x60000, but the message announces 32x24"),
            std::string::npos)
      << *checked;
  cv::Mat gray;
  const auto decoded = stages::imageToGray(hostile, &gray);
  ASSERT_TRUE(decoded);
  EXPECT_EQ(*decoded, *checked);
  EXPECT_TRUE(gray.empty());
}

TEST(ImageGray, AJpegPaddedWithZerosAfterItsEndDecodes) {
  // UVC cameras pad MJPEG frames with zeros after the end-of-image marker.
  vslam::image_t padded = jpegMessage(32, 24);
  padded.data.insert(padded.data.end(), 100, 0x00);
  EXPECT_FALSE(stages::checkImage(camera(32, 24), padded));
  cv::Mat gray;
  EXPECT_FALSE(stages::imageToGray(padded, &gray));
  EXPECT_EQ(gray.size(), cv::Size(32, 24));
}

TEST(ImageGray, TruncatedOrForeignJpegBytesAreRefused) {
  const vslam::image_t real = jpegMessage(32, 24);
  cv::Mat gray;
  auto refusal = [&](const std::vector<uint8_t>& bytes) {
    vslam::image_t m = real;
    m.data = bytes;
    const auto checked = stages::checkImage(camera(32, 24), m);
    const auto decoded = stages::imageToGray(m, &gray);
    EXPECT_TRUE(gray.empty());
    EXPECT_EQ(checked, decoded);
    return checked.value_or("accepted");
  };
  auto contains = [](const std::string& text, const std::string& part) {
    return text.find(part) != std::string::npos;
  };

  // Cut in the scan: the header is fine, the end-of-image marker missing
  // (OpenCV would decode it, the missing part gray).
  const std::vector<uint8_t> cut_in_scan(real.data.begin(), real.data.end() - 40);
  EXPECT_PRED2(contains, refusal(cut_in_scan), "JPEG truncated (no end-of-image marker");

  // Cut in the header, even with an end-of-image marker added back.
  const size_t sof = segmentOffset(real.data, 0xC0);
  ASSERT_GT(sof, 0u);
  std::vector<uint8_t> cut_in_header(real.data.begin(),
                                     real.data.begin() + static_cast<long>(sof) + 6);
  cut_in_header.push_back(0xFF);
  cut_in_header.push_back(0xD9);
  EXPECT_PRED2(contains, refusal(cut_in_header), "malformed JPEG header: ");

  // No frame header at all: start and end of image only.
  EXPECT_PRED2(contains, refusal({0xFF, 0xD8, 0xFF, 0xD9}), "malformed JPEG header: ");
  // A segment length pointing past the end.
  std::vector<uint8_t> long_segment = {0xFF, 0xD8, 0xFF, 0xE0, 0xFF, 0xF0, 0x00, 0xFF, 0xD9};
  EXPECT_PRED2(contains, refusal(long_segment), "malformed JPEG header: ");

  // PNG bytes labelled JPEG: imdecode would read them, unchecked.
  std::vector<uint8_t> png;
  cv::imencode(".png", cv::Mat(24, 32, CV_8UC1, cv::Scalar(7)), png);
  EXPECT_PRED2(contains, refusal(png), "not a JPEG");
  EXPECT_PRED2(contains, refusal({1, 2, 3}), "not a JPEG");
  EXPECT_PRED2(contains, refusal({}), "not a JPEG");
}

TEST(ImageGray, AJpegWhoseScanDataIsDamagedIsRefused) {
  cv::theRNG().state = 20261126;  // the same image whichever tests ran before
  // A color JPEG decodes to the gray OpenCV's imdecode gives.
  const vslam::image_t color = jpegMessage(64, 48, CV_8UC3);
  cv::Mat gray;
  ASSERT_FALSE(stages::imageToGray(color, &gray));
  EXPECT_EQ(cv::norm(gray, cv::imdecode(color.data, cv::IMREAD_GRAYSCALE), cv::NORM_INF), 0.0);

  // A frame that lost the last two thirds of its scan data (the last USB or
  // network packets), closed by its end marker all the same: the header
  // check passes it; libjpeg runs out of data before the last blocks, warns
  // and would fill them with gray; decoding refuses it.
  const size_t sos = segmentOffset(color.data, 0xDA);
  ASSERT_GT(sos, 0u);
  const size_t scan = sos + 2 + (size_t{color.data[sos + 2]} << 8 | color.data[sos + 3]);
  const size_t scan_bytes = color.data.size() - 2 - scan;
  vslam::image_t damaged = color;
  damaged.data.erase(damaged.data.begin() + static_cast<long>(scan + scan_bytes / 3),
                     damaged.data.end() - 2);
  EXPECT_FALSE(stages::checkImage(camera(64, 48), damaged));
  const auto refused = stages::imageToGray(damaged, &gray);
  ASSERT_TRUE(refused);
  EXPECT_NE(refused->find("damaged JPEG: Corrupt JPEG data"), std::string::npos) << *refused;
  EXPECT_TRUE(gray.empty());

  // Bytes between the scan and the end marker, as many UVC cameras write,
  // are not damage: the image decodes as before.
  vslam::image_t extraneous = color;
  extraneous.data.insert(extraneous.data.end() - 2, {0x12, 0x34, 0x56});
  ASSERT_FALSE(stages::imageToGray(extraneous, &gray));
  EXPECT_EQ(cv::norm(gray, cv::imdecode(color.data, cv::IMREAD_GRAYSCALE), cv::NORM_INF), 0.0);
}
