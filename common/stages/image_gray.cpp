#include "stages/image_gray.hpp"

#include <csetjmp>
#include <opencv2/imgproc.hpp>

// clang-format off
#include <cstdio>  // before jpeglib.h, which uses FILE without including <stdio.h>
#include <jpeglib.h>
#include <jerror.h>
// clang-format on

namespace vslam::stages {
namespace {

std::string sizeText(int64_t width, int64_t height) {
  return std::to_string(width) + "x" + std::to_string(height);
}

// Why the pixels of a raw (gray8, bgr8) image cannot be read as announced.
std::optional<std::string> rawDataProblem(const vslam::image_t& msg, int channels) {
  if (msg.width <= 0 || msg.height <= 0) {
    return "image size " + sizeText(msg.width, msg.height);
  }
  if (msg.row_stride < static_cast<int64_t>(msg.width) * channels ||
      msg.data.size() < static_cast<size_t>(msg.height) * static_cast<size_t>(msg.row_stride)) {
    return std::string("image data shorter than height x row_stride");
  }
  return std::nullopt;
}

// libjpeg reports errors through a callback that must not return: it jumps
// back to the function that set the trap (libjpeg is C, an exception must not
// cross it).
struct JpegErrorTrap {
  jpeg_error_mgr manager;  // first: libjpeg hands the callbacks &manager
  std::jmp_buf jump;
  char message[JMSG_LENGTH_MAX];
};

[[noreturn]] void jumpOnJpegError(j_common_ptr cinfo) {
  auto* trap = reinterpret_cast<JpegErrorTrap*>(cinfo->err);
  trap->manager.format_message(cinfo, trap->message);
  std::longjmp(trap->jump, 1);
}

// A warning (level -1) is data libjpeg would work around: corrupt markers,
// or the bytes ending before the header does. In a header that is refused.
// Trace messages (levels 0 and up) are ignored.
void jumpOnJpegWarning(j_common_ptr cinfo, int level) {
  if (level < 0) jumpOnJpegError(cinfo);
}

// Every libjpeg error jumps to the trap, and so does a warning.
void armJpegTrap(jpeg_decompress_struct* cinfo, JpegErrorTrap* trap) {
  cinfo->err = jpeg_std_error(&trap->manager);
  trap->manager.error_exit = jumpOnJpegError;
  trap->manager.emit_message = jumpOnJpegWarning;
}

// jpeg_read_header over data[0, size): true and the header in *cinfo, or
// false and libjpeg's message in trap->message. Kept free of C++ objects,
// whose destructors the jump would skip.
bool parseJpegHeader(const uint8_t* data, size_t size, jpeg_decompress_struct* cinfo,
                     JpegErrorTrap* trap) {
  if (setjmp(trap->jump) != 0) return false;
  jpeg_create_decompress(cinfo);
  jpeg_mem_src(cinfo, data, static_cast<unsigned long>(size));
  jpeg_read_header(cinfo, TRUE);  // an image, not tables only
  return true;
}

// In the scan, a warning is damage: a frame that lost part of its data
// (a USB or network packet) decodes to gray or smeared blocks, which would
// make features of their own. Extraneous bytes before a marker, which many
// UVC cameras write after their data, are not (so a loss whose remaining
// bytes happen to decode to every block passes: it looks the same).
void jumpOnJpegScanWarning(j_common_ptr cinfo, int level) {
  if (level < 0 && cinfo->err->msg_code != JWRN_EXTRANEOUS_DATA) jumpOnJpegError(cinfo);
}

// Decodes data[0, size) as gray into rows of `stride` bytes at pixels, which
// hold width x height: true, or false and why in trap->message. Free of C++
// objects, as parseJpegHeader.
bool decompressJpegGray(const uint8_t* data, size_t size, int width, int height, uint8_t* pixels,
                        size_t stride, jpeg_decompress_struct* cinfo, JpegErrorTrap* trap) {
  if (setjmp(trap->jump) != 0) return false;
  jpeg_create_decompress(cinfo);
  jpeg_mem_src(cinfo, data, static_cast<unsigned long>(size));
  jpeg_read_header(cinfo, TRUE);
  cinfo->out_color_space = JCS_GRAYSCALE;
  jpeg_start_decompress(cinfo);
  if (cinfo->output_width != static_cast<JDIMENSION>(width) ||
      cinfo->output_height != static_cast<JDIMENSION>(height) || cinfo->output_components != 1) {
    std::snprintf(trap->message, sizeof trap->message, "decodes to %ux%u with %d components",
                  cinfo->output_width, cinfo->output_height, cinfo->output_components);
    return false;
  }
  trap->manager.emit_message = jumpOnJpegScanWarning;
  while (cinfo->output_scanline < cinfo->output_height) {
    JSAMPROW row = pixels + static_cast<size_t>(cinfo->output_scanline) * stride;
    jpeg_read_scanlines(cinfo, &row, 1);
  }
  jpeg_finish_decompress(cinfo);
  return true;
}

// Why the JPEG in msg cannot be decoded at the size the message announces.
std::optional<std::string> jpegDataProblem(const vslam::image_t& msg) {
  JpegHeader header;
  if (auto problem = readJpegHeader(msg.data.data(), msg.data.size(), &header)) return problem;
  if (header.width != msg.width || header.height != msg.height) {
    return "JPEG header announces " + sizeText(header.width, header.height) +
           ", but the message announces " + sizeText(msg.width, msg.height);
  }
  if (header.components != 1 && header.components != 3) {
    return "JPEG with " + std::to_string(header.components) +
           " components (expected 1, gray, or 3, color)";
  }
  return std::nullopt;
}

}  // namespace

std::optional<std::string> readJpegHeader(const uint8_t* data, size_t size, JpegHeader* header) {
  // Bytes that are not a JPEG at all (PNG or TIFF labelled JPEG) get a
  // refusal that says so.
  if (size < 4 || data[0] != 0xFF || data[1] != 0xD8 || data[2] != 0xFF) {
    return std::string("not a JPEG (no start-of-image marker)");
  }
  // Some UVC cameras pad their MJPEG frames with zeros after the end marker.
  size_t end = size;
  while (end > 4 && data[end - 1] == 0x00) --end;
  if (data[end - 2] != 0xFF || data[end - 1] != 0xD9) {
    return std::string("JPEG truncated (no end-of-image marker at its end)");
  }
  jpeg_decompress_struct cinfo{};
  JpegErrorTrap trap{};
  armJpegTrap(&cinfo, &trap);
  const bool parsed = parseJpegHeader(data, size, &cinfo, &trap);
  if (parsed) {
    header->width = static_cast<int>(cinfo.image_width);
    header->height = static_cast<int>(cinfo.image_height);
    header->components = cinfo.num_components;
  }
  jpeg_destroy_decompress(&cinfo);
  if (!parsed) return std::string("malformed JPEG header: ") + trap.message;
  return std::nullopt;
}

std::optional<std::string> checkImage(const config::CameraConfig& camera,
                                      const vslam::image_t& msg) {
  if (msg.width != camera.width || msg.height != camera.height) {
    return "image " + sizeText(msg.width, msg.height) + ", but camera '" + camera.name +
           "' is calibrated for " + sizeText(camera.width, camera.height);
  }
  switch (msg.encoding) {
    case vslam::image_t::ENCODING_GRAY8:
    case vslam::image_t::ENCODING_BGR8: {
      return rawDataProblem(msg, msg.encoding == vslam::image_t::ENCODING_GRAY8 ? 1 : 3);
    }
    case vslam::image_t::ENCODING_JPEG:
      return jpegDataProblem(msg);
    default:
      return "unknown encoding " + std::to_string(msg.encoding);
  }
}

std::optional<std::string> imageToGray(const vslam::image_t& msg, cv::Mat* gray) {
  if (msg.encoding == vslam::image_t::ENCODING_JPEG) {
    // Checked again here: the pixels are allocated at the announced size.
    if (auto problem = jpegDataProblem(msg)) return problem;
    gray->create(msg.height, msg.width, CV_8UC1);
    jpeg_decompress_struct cinfo{};
    JpegErrorTrap trap{};
    armJpegTrap(&cinfo, &trap);
    const bool decoded = decompressJpegGray(msg.data.data(), msg.data.size(), msg.width, msg.height,
                                            gray->data, gray->step[0], &cinfo, &trap);
    jpeg_destroy_decompress(&cinfo);
    if (!decoded) {
      gray->release();
      return std::string("damaged JPEG: ") + trap.message;
    }
    return std::nullopt;
  }
  const bool is_gray = msg.encoding == vslam::image_t::ENCODING_GRAY8;
  if (!is_gray && msg.encoding != vslam::image_t::ENCODING_BGR8) {
    return "unknown encoding " + std::to_string(msg.encoding);
  }
  // Checked again here: the view below reads height x row_stride bytes.
  if (auto problem = rawDataProblem(msg, is_gray ? 1 : 3)) return problem;
  const cv::Mat view(msg.height, msg.width, is_gray ? CV_8UC1 : CV_8UC3,
                     const_cast<uint8_t*>(msg.data.data()), static_cast<size_t>(msg.row_stride));
  if (is_gray) {
    view.copyTo(*gray);
  } else {
    cv::cvtColor(view, *gray, cv::COLOR_BGR2GRAY);
  }
  return std::nullopt;
}

}  // namespace vslam::stages
