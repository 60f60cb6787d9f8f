#include "stepcal/programs/configuration.hpp"

#include <cmath>
#include <cstdio>
#include <vector>

#include "stepcal/common/error.hpp"

namespace stepcal::programs {
namespace {

[[noreturn]] void badWord(const Target& t, const std::string& path, const std::string& expected) {
  throw InputError("configuration " + std::string(t.configuration) + ": expected " + expected, path,
                   t.line, std::to_string(t.column));
}

/// KRL's S or T: decimal, or 'B0101' (binary).
std::optional<int> kukaBits(const std::string& text) {
  if (text.size() >= 3 && text.front() == '\'' && text.back() == '\'' && (text[1] == 'B' || text[1] == 'b')) {
    int v = 0;
    for (size_t i = 2; i + 1 < text.size(); ++i) {
      if (text[i] != '0' && text[i] != '1') return std::nullopt;
      v = 2 * v + (text[i] - '0');
    }
    return text.size() > 3 ? std::optional<int>(v) : std::nullopt;
  }
  if (text.empty() || text.find_first_not_of("0123456789") != std::string::npos || text.size() > 3) return std::nullopt;
  return std::stoi(text);
}

ConfigurationWord kuka(const Target& t, const std::string& path) {
  ConfigurationWord w;
  w.language = Language::kKrl;
  // As the reader joins them: "S <value> T <value>", either missing.
  std::vector<std::string> parts;
  size_t at = 0;
  while (at < t.configuration.size()) {
    const size_t space = t.configuration.find(' ', at);
    parts.push_back(t.configuration.substr(at, space == std::string::npos ? std::string::npos : space - at));
    at = space == std::string::npos ? t.configuration.size() : space + 1;
  }
  for (size_t i = 0; i + 1 < parts.size(); i += 2) {
    const std::optional<int> bits = kukaBits(parts[i + 1]);
    if (!bits || (parts[i] == "S" && *bits > 7) || *bits > 63) badWord(t, path, "S 0…7 and T 0…63, decimal or 'B…'");
    (parts[i] == "S" ? w.kuka_status : w.kuka_turn) = *bits;
  }
  return w;
}

ConfigurationWord abb(const Target& t, const std::string& path) {
  ConfigurationWord w;
  w.language = Language::kRapid;
  AbbConfData c;
  if (std::sscanf(t.configuration.c_str(), "[%d ,%d ,%d ,%d ]", &c.cf1, &c.cf4, &c.cf6, &c.cfx) != 4 || c.cfx < 0 || c.cfx > 7) {
    badWord(t, path, "[cf1,cf4,cf6,cfx], integers, cfx 0…7");
  }
  w.abb = c;
  return w;
}

ConfigurationWord fanuc(const Target& t, const std::string& path) {
  ConfigurationWord w;
  w.language = Language::kFanucTp;
  char flip = 0, up = 0, front = 0;
  FanucConfig c;
  if (std::sscanf(t.configuration.c_str(), " %c %c %c , %d , %d , %d", &flip, &up, &front, &c.turn1, &c.turn4, &c.turn6) != 6 ||
      std::string("FN").find(char(std::toupper(flip))) == std::string::npos ||
      std::string("UD").find(char(std::toupper(up))) == std::string::npos ||
      std::string("TB").find(char(std::toupper(front))) == std::string::npos) {
    badWord(t, path, "'F|N U|D T|B, t1, t4, t6'");
  }
  c.flip = std::toupper(flip) == 'F';
  c.up = std::toupper(up) == 'U';
  c.front = std::toupper(front) == 'T';
  w.fanuc = c;
  return w;
}

}  // namespace

std::optional<ConfigurationWord> readConfiguration(Language language, const Target& t, const std::string& path) {
  if (t.kind != TargetKind::kCartesian || t.configuration.empty()) return std::nullopt;
  switch (language) {
    case Language::kKrl: {
      ConfigurationWord w = kuka(t, path);
      if (!w.kuka_status) return std::nullopt;
      return w;
    }
    case Language::kRapid: return abb(t, path);
    case Language::kFanucTp: return fanuc(t, path);
    case Language::kUrScript: return std::nullopt;
  }
  return std::nullopt;
}

ArmBranch branchNamed(const ConfigurationWord& w, const ControllerJoints& joints) {
  if (w.abb) return branchOfAbbCfx(w.abb->cfx, joints);
  if (w.fanuc) return branchOfFanucConfig(*w.fanuc, joints);
  return branchOfKukaStatus(*w.kuka_status, joints);
}

void applyTurns(const ConfigurationWord& w, const KinematicChain& chain, const ControllerJoints& joints,
                JointVector& q) {
  const JointVector before = q;
  if (w.abb) applyAbbQuadrants(*w.abb, q);
  if (w.fanuc) {
    applyFanucTurn(0, w.fanuc->turn1, q);
    applyFanucTurn(3, w.fanuc->turn4, q);
    applyFanucTurn(5, w.fanuc->turn6, q);
  }
  if (w.kuka_turn) applyKukaTurn(*w.kuka_turn, q);
  // A turn the limits do not allow stays where the closed form put it (then reported).
  const JointVector chain_q = chainFromController(joints, q);
  for (int j = 0; j < 6; ++j) {
    const ChainJoint& limits = chain.joints()[size_t(j)];
    if (chain_q[j] < limits.lower_rad || chain_q[j] > limits.upper_rad) q[j] = before[j];
  }
}

bool sameConfiguration(const ConfigurationWord& w, const ArmBranch& branch, const JointVector& q, std::string& theirs) {
  char text[64];
  if (w.abb) {
    const AbbConfData c = abbConfData(branch, q);
    std::snprintf(text, sizeof text, "[%d,%d,%d,%d]", c.cf1, c.cf4, c.cf6, c.cfx);
    theirs = text;
    return c.cf1 == w.abb->cf1 && c.cf4 == w.abb->cf4 && c.cf6 == w.abb->cf6 && c.cfx == w.abb->cfx;
  }
  if (w.fanuc) {
    const FanucConfig c = fanucConfig(branch, q);
    std::snprintf(text, sizeof text, "%c %c %c, %d, %d, %d", c.flip ? 'F' : 'N', c.up ? 'U' : 'D',
                  c.front ? 'T' : 'B', c.turn1, c.turn4, c.turn6);
    theirs = text;
    const FanucConfig& f = *w.fanuc;
    return c.flip == f.flip && c.up == f.up && c.front == f.front && c.turn1 == f.turn1 &&
           c.turn4 == f.turn4 && c.turn6 == f.turn6;
  }
  const KukaStatusTurn c = kukaStatusTurn(branch, q);
  std::snprintf(text, sizeof text, "S %d T %d", c.status, c.turn);
  theirs = text;
  return c.status == *w.kuka_status && (!w.kuka_turn || c.turn == *w.kuka_turn);
}

}  // namespace stepcal::programs
