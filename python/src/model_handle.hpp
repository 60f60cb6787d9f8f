// stepcal.Model: a model file loaded for the runtime's calls, shared by the Python objects that
// hold it (immutable, so calls from several Python threads may run at once).
#pragma once

#include <memory>
#include <string>

#include "stepcal/common/model_file.hpp"
#include "stepcal/runtime/corrector.hpp"

namespace stepcal::python {

using RuntimeModelPtr = std::shared_ptr<const runtime::RuntimeModel>;

class ModelHandle {
 public:
  /// An in-memory model (a calibration's or a diagnosis's); its id is that of its file's bytes.
  explicit ModelHandle(CalibratedModel model);
  /// Loads and validates a model file. Throws InputError.
  static ModelHandle load(const std::string& path);
  const RuntimeModelPtr& runtime() const { return runtime_; }

 private:
  ModelHandle() = default;
  RuntimeModelPtr runtime_;
};

}  // namespace stepcal::python
