#include "config/param_table.hpp"

namespace vslam::config {

namespace {

// A table cell: no line breaks, and a '|' escaped so it does not end the cell.
std::string cell(const std::string& text) {
  std::string out;
  for (char c : text) {
    if (c == '|') {
      out += "\\|";
    } else if (c == '\n') {
      out += ' ';
    } else {
      out += c;
    }
  }
  return out;
}

}  // namespace

std::string markdownTable(const std::vector<ParamDoc>& rows, const std::string& configured_header) {
  bool any_configured = false;
  for (const auto& r : rows) any_configured = any_configured || !r.configured.empty();
  const bool with_configured = any_configured && !configured_header.empty();
  std::ostringstream os;
  os << "| key | unit | default | range |"
     << (with_configured ? " " + configured_header + " |" : "") << " meaning |\n";
  os << "|---|---|---|---|" << (with_configured ? "---|" : "") << "---|\n";
  for (const auto& r : rows) {
    os << "| `" << r.key << "` | " << cell(r.unit) << " | " << cell(r.default_value) << " | "
       << cell(r.range) << " | ";
    if (with_configured) os << cell(r.configured) << " | ";
    os << cell(r.meaning) << " |\n";
  }
  return os.str();
}

}  // namespace vslam::config
