// `stepcal inspect`: what a model file holds.
#include <cstdint>
#include <iostream>
#include <memory>
#include <string>

#include "stepcal/common/model_file.hpp"
#include "stepcal/common/urdf.hpp"
#include "stepcal/report/report.hpp"
#include "subcommands.hpp"

namespace stepcal::cli {

Subcommand addInspectCommand(CLI::App& app) {
  auto model_path = std::make_shared<std::string>();
  CLI::App* inspect = app.add_subcommand("inspect", "print what a model file holds");
  inspect->add_option("model", *model_path, "model file")->required();
  return {inspect, [model_path] {
            const std::string bytes = readTextFile(*model_path);
            std::cout << report::formatModel(parseModel(reinterpret_cast<const uint8_t*>(bytes.data()),
                                                     bytes.size(), *model_path),
                                          bytes.size());
          }};
}

}  // namespace stepcal::cli
