// vslam-import: converts a TUM RGB-D-layout folder into an LCM log on the
// stack's channels (see common/eval/tum_import.hpp, docs/evaluation.md).
#include <iostream>

#include "eval/import_cli.hpp"
#include "util/log.hpp"

int main(int argc, char** argv) {
  vslam::log::setProcessName("import");
  return vslam::eval::runImportCli({argv + 1, argv + argc}, std::cout, std::cerr);
}
