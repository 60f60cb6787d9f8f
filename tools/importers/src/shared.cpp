// Pieces the importers share (see shared.hpp).
#include "shared.hpp"

#include <filesystem>
#include <optional>
#include <string_view>
#include <vector>

#include "stepcal/common/csv.hpp"
#include "stepcal/common/error.hpp"
#include "stepcal/common/lie.hpp"
#include "stepcal/common/text_number.hpp"
#include "stepcal/common/urdf.hpp"

namespace stepcal::importers {

namespace fs = std::filesystem;

std::string readExistingFile(const std::string& path, const std::string& what) {
  std::error_code ec;
  if (!fs::is_regular_file(path, ec)) {
    throw InputError(what + (fs::is_directory(path, ec) ? " is a folder" : " not found") +
                         "; expected a readable file",
                     path);
  }
  return readTextFile(path);
}

Pose readRigidTransformFile(const std::string& path, const std::string& what,
                            double metres_per_unit) {
  const std::string text = readExistingFile(path, what);
  std::vector<std::string_view> lines = splitLines(text);
  while (!lines.empty() && lines.back().find_first_not_of(" \t") == std::string_view::npos) {
    lines.pop_back();  // blank lines after the matrix
  }
  if (lines.size() != 4) {
    throw InputError(
        "has " + std::to_string(lines.size()) + " lines; expected the 4 rows of a 4x4 transform",
        path);
  }
  Eigen::Matrix4d M;
  for (int r = 0; r < 4; ++r) {
    std::vector<std::string_view> entries;
    for (std::string_view token : splitFields(lines[static_cast<size_t>(r)], ' ')) {
      for (std::string_view part : splitFields(token, '\t')) {
        if (!part.empty()) entries.push_back(part);
      }
    }
    if (entries.size() != 4) {
      throw InputError(
          "row has " + std::to_string(entries.size()) + " numbers; expected 4 separated by spaces",
          path, r + 1);
    }
    for (int k = 0; k < 4; ++k) {
      const std::string_view entry = entries[static_cast<size_t>(k)];
      const std::optional<double> v = parseFinite(entry);
      if (!v) {
        throw InputError("expected a number with a decimal point, got " + inQuotes(entry), path,
                         r + 1, std::to_string(k + 1));
      }
      M(r, k) = *v;
    }
  }
  const Mat3 R = M.topLeftCorner<3, 3>();
  const double orthonormality = (R.transpose() * R - Mat3::Identity()).cwiseAbs().maxCoeff();
  if (M.row(3) != Eigen::RowVector4d(0, 0, 0, 1) || orthonormality > 1e-6 ||
      R.determinant() < 0.0) {
    throw InputError(
        "expected a rigid transform (rotation block orthonormal to 1e-6 with "
        "determinant +1, last row 0 0 0 1), got a rotation block off by " +
            formatShortest(orthonormality) + " and last row " + formatShortest(M(3, 0)) + " " +
            formatShortest(M(3, 1)) + " " + formatShortest(M(3, 2)) + " " + formatShortest(M(3, 3)),
        path);
  }
  Pose X = Pose::Identity();
  X.linear() = lie::projectToSO3(R);  // such files have few decimals
  X.translation() = M.topRightCorner<3, 1>() * metres_per_unit;
  return X;
}

std::string withFixedLink(const std::string& urdf, const std::string& parent,
                          const std::string& child, const Pose& X_ParentChild,
                          const std::string& comment, const std::string& source) {
  const size_t end = urdf.rfind("</robot>");
  if (end == std::string::npos) {
    throw InputError("expected a URDF robot description ending with </robot>", source);
  }
  const UrdfOrigin origin = urdfOriginOf(X_ParentChild);
  const std::string block =
      "  <!-- " + comment + " -->\n"
      "  <link name=\"" + child + "\"/>\n"
      "  <joint name=\"" + parent + "-" + child + "\" type=\"fixed\">\n"
      "    <parent link=\"" + parent + "\"/><child link=\"" + child + "\"/>\n"
      "    <origin xyz=\"" + origin.xyz + "\" rpy=\"" + origin.rpy + "\"/>\n"
      "  </joint>\n";
  return urdf.substr(0, end) + block + urdf.substr(end);
}

}  // namespace stepcal::importers
