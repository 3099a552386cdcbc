// Every LCM message type as it arrives from the network: the first byte picks
// the type, the rest is the payload. bus::checkedDecode must reject what is
// not exactly one well-formed message (a count claiming more bytes than
// there are, a truncated string, trailing bytes) without allocating for it;
// what it accepts must encode and decode again to the same bytes; and the
// handlers' own checks (a landmark's points, an image's size and encoding,
// JPEG included) must answer without crashing.
#include <cstdio>
#include <cstdlib>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include "bus/checked_decode.hpp"
#include "fuzz_target.hpp"
#include "stages/frontend_stage.hpp"
#include "stages/image_gray.hpp"
#include "status/status_cli.hpp"
#include "transport/message_fill.hpp"

namespace {

using namespace vslam::transport_test;

template <class Msg>
std::string encode(const Msg& m) {
  std::string bytes(static_cast<size_t>(m.getEncodedSize()), '\0');
  m.encode(bytes.data(), 0, static_cast<int>(bytes.size()));
  return bytes;
}

// What the stages do with a message of this type once it decoded.
template <class Msg>
void handle(const Msg&) {}
void handle(const vslam::landmark_t& m) { (void)vslam::stages::checkLandmarkMessage(m); }
void handle(const vslam::image_t& m) {
  cv::Mat gray;
  (void)vslam::stages::imageToGray(m, &gray);
}
// vslam-status: whatever a HEALTH message holds, the board stays printable.
void handle(const vslam::health_t& m) {
  vslam::status::StatusBoard board;
  board.add(vslam::status::healthSampleOf(m, 1.0));
  board.add(vslam::status::healthSampleOf(m, 2.0));
  for (const char c : vslam::status::renderBoard(board.rows(2.5), 100)) {
    if (c != '\n' && (c < 0x20 || c > 0x7e)) std::abort();
  }
}

template <class Msg>
[[noreturn]] void fail(const std::string& what) {
  std::fprintf(stderr, "%s: %s\n", vslam::wire::Walker<Msg>::kName, what.c_str());
  std::abort();
}

template <class Msg>
void decodeAndHandle(const uint8_t* data, size_t size) {
  Msg msg;
  std::string why;
  if (!vslam::bus::checkedDecode(msg, data, size, &why)) {
    if (why.empty()) fail<Msg>("rejected without saying why");
    return;
  }
  const std::string once = encode(msg);
  Msg again;
  if (!vslam::bus::checkedDecode(again, once.data(), once.size(), &why)) {
    fail<Msg>("its own encoding does not decode: " + why);
  }
  if (encode(again) != once) fail<Msg>("encoding, decoding and encoding again changes it");
  handle(msg);
}

template <class... Ts>
void dispatch(TypeList<Ts...>, size_t index, const uint8_t* data, size_t size) {
  size_t i = 0;
  ((i++ == index ? decodeAndHandle<Ts>(data, size) : void()), ...);
}

template <class... Ts>
constexpr size_t count(TypeList<Ts...>) {
  return sizeof...(Ts);
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size == 0) return 0;
  dispatch(AllTypes{}, data[0] % count(AllTypes{}), data + 1, size - 1);
  return 0;
}

std::vector<std::string> vslam::fuzz::seeds() {
  std::vector<std::string> out;
  size_t index = 0;
  forEachType(AllTypes{}, [&](auto tag) {
    for (int s = 0; s < 2; ++s) {
      typename decltype(tag)::type m;
      fill(m, s);
      out.push_back(std::string(1, static_cast<char>(index)) + encode(m));
    }
    ++index;
  });
  // A JPEG frame (image_t is the first type), for the decoder behind imageToGray.
  vslam::image_t jpeg;
  fill(jpeg, 0);
  cv::Mat frame(24, 32, CV_8UC1);
  cv::randu(frame, 0, 255);
  std::vector<uint8_t> bytes;
  cv::imencode(".jpg", frame, bytes);
  jpeg.encoding = vslam::image_t::ENCODING_JPEG;
  jpeg.width = frame.cols;
  jpeg.height = frame.rows;
  jpeg.row_stride = 0;
  jpeg.data = bytes;
  jpeg.data_size = static_cast<int32_t>(bytes.size());
  out.push_back(std::string(1, '\0') + encode(jpeg));
  return out;
}
