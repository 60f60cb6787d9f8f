#include "stepcal/common/urdf.hpp"

#include <console_bridge/console.h>
#include <urdf_parser/urdf_parser.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <limits>
#include <sstream>
#include <utility>

#include "stepcal/common/error.hpp"
#include "stepcal/common/lie.hpp"
#include "stepcal/common/text_number.hpp"
#include "urdf_model.hpp"

namespace stepcal {
namespace {

// Collects urdfdom's console messages so a parse failure can say why.
class CapturingHandler : public console_bridge::OutputHandler {
 public:
  void log(const std::string& text, console_bridge::LogLevel level, const char*, int) override {
    if (level >= console_bridge::CONSOLE_BRIDGE_LOG_WARN) {
      if (!messages.empty()) messages += "; ";
      messages += text;
    }
  }
  std::string messages;
};

/// Bytes of the UTF-8 character a lead byte starts (1 … 4), 0 for a byte that starts none.
int utf8Length(unsigned char lead) {
  if (lead < 0x80) return 1;
  if (lead >= 0xC2 && lead <= 0xDF) return 2;
  if (lead >= 0xE0 && lead <= 0xEF) return 3;
  if (lead >= 0xF0 && lead <= 0xF4) return 4;
  return 0;
}

/// Throws InputError (line and column of the first bad byte) unless text is UTF-8 without NUL
/// bytes. TinyXML, urdfdom's parser, skips as many bytes as a lead byte announces, so a character
/// cut off at the end sends it past the text's end (found by tests/fuzz/fuzz_urdf.cpp), and it
/// stops at a NUL, dropping what follows without a word.
void requireUtf8Text(const std::string& text, const std::string& source) {
  int line = 1;
  size_t line_start = 0;
  for (size_t i = 0; i < text.size();) {
    const auto lead = static_cast<unsigned char>(text[i]);
    const int length = utf8Length(lead);
    bool complete = lead != 0 && length > 0 && i + static_cast<size_t>(length) <= text.size();
    for (int k = 1; complete && k < length; ++k) {
      complete = (static_cast<unsigned char>(text[i + static_cast<size_t>(k)]) & 0xC0) == 0x80;
    }
    if (!complete) {
      char byte[8];
      std::snprintf(byte, sizeof byte, "0x%02X", lead);
      const std::string what = lead == 0 ? std::string("a NUL byte")
                                         : "byte " + std::string(byte) +
                                               ", which starts no complete UTF-8 character,";
      throw InputError(what + " at column " + std::to_string(i - line_start + 1) +
                           "; expected UTF-8 text (a URDF is XML)",
                       source, line);
    }
    if (lead == '\n') {
      ++line;
      line_start = i + 1;
    }
    i += static_cast<size_t>(length);
  }
}

bool isRevolute(const urdf::Joint& j) {
  return j.type == urdf::Joint::REVOLUTE || j.type == urdf::Joint::CONTINUOUS;
}

// Adds the inertials of link and every link hanging from it by fixed joints (X_BodyLink: the
// link's pose in the body frame) to mass and first moment; true when any had an <inertial>.
bool addRigidInertials(const urdf::ModelInterface& model, const urdf::Link& link,
                       const Pose& X_BodyLink, double& mass, Vec3& first_moment,
                       const std::string& source) {
  bool found = false;
  if (link.inertial) {
    const double m = link.inertial->mass;
    if (!(std::isfinite(m) && m >= 0.0)) {
      throw InputError("link '" + link.name + "' has <mass value=\"" + std::to_string(m) +
                           "\">; expected a finite mass >= 0 kg",
                       source);
    }
    const Pose X_BodyCom = X_BodyLink * poseFromUrdf(link.inertial->origin);
    mass += link.inertial->mass;
    first_moment += link.inertial->mass * X_BodyCom.translation();
    found = true;
  }
  for (const urdf::JointSharedPtr& j : link.child_joints) {
    if (j->type != urdf::Joint::FIXED) continue;
    const urdf::LinkConstSharedPtr child = model.getLink(j->child_link_name);
    if (child) {
      found = addRigidInertials(model, *child,
                                X_BodyLink * poseFromUrdf(j->parent_to_joint_origin_transform),
                                mass, first_moment, source) ||
              found;
    }
  }
  return found;
}

// urdfdom accepts loops of joints away from the root: a joint whose child is its parent, a link
// taken as child by a second joint (the later one becomes its parent), a ring of links. Walking
// up or down one never ends. Empty when the joints form a tree, else which link closes a loop.
std::string loopProblem(const urdf::ModelInterface& model) {
  for (const auto& [name, joint] : model.joints_) {
    const urdf::LinkConstSharedPtr child = model.getLink(joint->child_link_name);
    if (child && child->parent_joint != joint) {
      return "link '" + joint->child_link_name + "' is the child of joints '" + name + "' and '" +
             (child->parent_joint ? child->parent_joint->name : std::string("?")) +
             "'; expected one parent joint per link (a tree)";
    }
  }
  for (const auto& [name, link] : model.links_) {
    urdf::LinkConstSharedPtr current = link;
    // In a tree every link reaches the root within as many steps as there are joints.
    for (size_t steps = 0; current && current->parent_joint; ++steps) {
      if (steps > model.joints_.size()) {
        return "the joints above link '" + name +
               "' form a loop (they never reach the root link); expected a tree";
      }
      current = model.getLink(current->parent_joint->parent_link_name);
    }
  }
  return {};
}

}  // namespace

Pose poseFromUrdf(const urdf::Pose& p) {
  Pose X = Pose::Identity();
  X.translation() = Vec3(p.position.x, p.position.y, p.position.z);
  X.linear() =
      Eigen::Quaterniond(p.rotation.w, p.rotation.x, p.rotation.y, p.rotation.z)
          .normalized()
          .toRotationMatrix();
  return X;
}

std::vector<urdf::JointConstSharedPtr> urdfPathFromBase(const urdf::ModelInterface& model,
                                                         const std::string& base,
                                                         const std::string& link,
                                                         const std::string& source,
                                                         const std::string& role) {
  std::vector<urdf::JointConstSharedPtr> path;
  urdf::LinkConstSharedPtr current = model.getLink(link);
  if (!current) {
    std::string names;
    for (const auto& [name, l] : model.links_) names += (names.empty() ? "" : ", ") + name;
    throw InputError(role + " '" + link + "' is not a link of the robot description (links: " +
                         names + ")",
                     source);
  }
  while (current->name != base) {
    const urdf::JointConstSharedPtr joint = current->parent_joint;
    if (!joint) {
      throw InputError(role + " '" + link + "' is not below base_link '" + base +
                           "' in the robot description; hint: check base_link and the joint tree",
                       source);
    }
    path.insert(path.begin(), joint);
    current = model.getLink(joint->parent_link_name);
  }
  return path;
}

urdf::ModelInterfaceSharedPtr parseUrdfOrThrow(const std::string& urdf_xml,
                                               const std::string& source) {
  requireUtf8Text(urdf_xml, source);
  CapturingHandler handler;
  console_bridge::useOutputHandler(&handler);
  urdf::ModelInterfaceSharedPtr model = urdf::parseURDF(urdf_xml);
  console_bridge::restorePreviousOutputHandler();
  if (!model) {
    throw InputError("not a valid URDF robot description: " +
                         (handler.messages.empty() ? std::string("parse failed") : handler.messages),
                     source);
  }
  const std::string loop = loopProblem(*model);
  if (!loop.empty()) {
    // The loop's links own each other through child_links; unlinked, the refused model is freed.
    for (const auto& [name, link] : model->links_) {
      link->child_links.clear();
      link->child_joints.clear();
    }
    throw InputError(loop, source);
  }
  return model;
}

KinematicChain chainFromUrdf(const std::string& urdf_xml, const std::string& base_link,
                             const std::string& tip_link,
                             const std::vector<std::string>& attached_links,
                             const std::string& source) {
  const urdf::ModelInterfaceSharedPtr model = parseUrdfOrThrow(urdf_xml, source);
  if (!model->getLink(base_link)) {
    throw InputError("base_link '" + base_link + "' is not a link of the robot description",
                     source);
  }

  std::vector<ChainJoint> joints;
  std::vector<Pose> initial;
  Pose X_accumulated = Pose::Identity();
  for (const urdf::JointConstSharedPtr& j :
       urdfPathFromBase(*model, base_link, tip_link, source, "tip_link")) {
    X_accumulated = X_accumulated * poseFromUrdf(j->parent_to_joint_origin_transform);
    if (j->type == urdf::Joint::FIXED) continue;
    if (!isRevolute(*j)) {
      throw InputError("joint '" + j->name +
                           "' is neither revolute, continuous nor fixed; stepcal models "
                           "revolute serial chains only",
                       source);
    }
    const Vec3 axis(j->axis.x, j->axis.y, j->axis.z);
    if (!(axis.norm() > 1e-9)) {
      throw InputError("joint '" + j->name + "' has a zero <axis>; expected a direction", source);
    }
    ChainJoint cj;
    cj.name = j->name;
    cj.twist_Local << Vec3::Zero(), axis.normalized();
    if (j->type == urdf::Joint::CONTINUOUS || !j->limits) {
      cj.lower_rad = -std::numeric_limits<double>::infinity();
      cj.upper_rad = std::numeric_limits<double>::infinity();
    } else {
      cj.lower_rad = j->limits->lower;
      cj.upper_rad = j->limits->upper;
    }
    joints.push_back(cj);
    initial.push_back(X_accumulated);
    X_accumulated = Pose::Identity();
  }
  if (joints.empty()) {
    throw InputError("no revolute joint between base_link '" + base_link + "' and tip_link '" +
                         tip_link + "'",
                     source);
  }
  if (joints.size() > static_cast<size_t>(kMaxJoints)) {
    throw InputError("chain has " + std::to_string(joints.size()) + " revolute joints; at most " +
                         std::to_string(kMaxJoints) + " are supported",
                     source);
  }
  initial.push_back(X_accumulated);

  std::vector<AttachedFrame> frames;
  for (const std::string& name : attached_links) {
    AttachedFrame f;
    f.name = name;
    f.X_ParentFrame = Pose::Identity();
    for (const urdf::JointConstSharedPtr& j :
         urdfPathFromBase(*model, base_link, name, source, "link")) {
      if (j->type == urdf::Joint::FIXED) {
        f.X_ParentFrame = f.X_ParentFrame * poseFromUrdf(j->parent_to_joint_origin_transform);
        continue;
      }
      if (f.parent >= static_cast<int>(joints.size()) ||
          joints[static_cast<size_t>(f.parent)].name != j->name) {
        throw InputError("link '" + name + "' moves with joint '" + j->name +
                             "', which is not on the chain from '" + base_link + "' to '" +
                             tip_link + "'",
                         source);
      }
      ++f.parent;
      f.X_ParentFrame = Pose::Identity();
    }
    frames.push_back(f);
  }
  return KinematicChain(std::move(joints), std::move(initial), std::move(frames));
}

std::optional<std::vector<double>> bodyMassesFromUrdf(const std::string& urdf_xml,
                                                      const std::string& base_link,
                                                      const std::string& tip_link,
                                                      const std::string& source) {
  const KinematicChain chain = chainFromUrdf(urdf_xml, base_link, tip_link, {}, source);
  const urdf::ModelInterfaceSharedPtr model = parseUrdfOrThrow(urdf_xml, source);
  std::vector<double> parameters;
  bool found = false;
  for (const urdf::JointConstSharedPtr& j :
       urdfPathFromBase(*model, base_link, tip_link, source, "tip_link")) {
    if (j->type == urdf::Joint::FIXED) continue;
    // Body k: joint k's child link (its frame is frame k) and what hangs from it rigidly.
    double mass = 0.0;
    Vec3 first_moment = Vec3::Zero();
    found = addRigidInertials(*model, *model->getLink(j->child_link_name), Pose::Identity(), mass,
                              first_moment, source) ||
            found;
    parameters.insert(parameters.end(), {mass, first_moment.x(), first_moment.y(),
                                         first_moment.z()});
  }
  STEPCAL_INVARIANT(parameters.size() == 4 * static_cast<size_t>(chain.dof()),
                    "one body per revolute joint");
  if (!found) return std::nullopt;
  return parameters;
}

UrdfChainEnds urdfChainEnds(const std::string& urdf_xml, const std::string& source) {
  const urdf::ModelInterfaceSharedPtr model = parseUrdfOrThrow(urdf_xml, source);
  const urdf::LinkConstSharedPtr root = model->getRoot();
  STEPCAL_INVARIANT(root != nullptr, "urdfdom's parser returns a model with a root link");
  // Depth-first over the tree: each leaf with the number of revolute joints above it.
  int most = -1;
  std::vector<std::string> deepest;
  std::vector<std::pair<urdf::LinkConstSharedPtr, int>> stack = {{root, 0}};
  while (!stack.empty()) {
    const auto [link, revolute] = stack.back();
    stack.pop_back();
    if (link->child_joints.empty()) {
      if (revolute > most) {
        most = revolute;
        deepest.clear();
      }
      if (revolute == most) deepest.push_back(link->name);
      continue;
    }
    for (const urdf::JointSharedPtr& j : link->child_joints) {
      const urdf::LinkConstSharedPtr child = model->getLink(j->child_link_name);
      if (child) stack.emplace_back(child, revolute + (isRevolute(*j) ? 1 : 0));
    }
  }
  if (most < 1) {
    throw InputError("no revolute joint below the root link '" + root->name +
                         "'; expected a serial arm",
                     source);
  }
  if (deepest.size() > 1) {
    std::sort(deepest.begin(), deepest.end());
    std::string names;
    for (const std::string& name : deepest) names += (names.empty() ? "" : ", ") + name;
    throw InputError("the links " + names + " all end a chain of " + std::to_string(most) +
                         " revolute joints below '" + root->name +
                         "'; expected one end of the arm (hint: name the tracked frame with "
                         "--tip-link)",
                     source);
  }
  return {root->name, deepest.front()};
}

std::string urdfRobotName(const std::string& urdf_xml, const std::string& source) {
  return parseUrdfOrThrow(urdf_xml, source)->getName();
}

bool urdfHasLink(const std::string& urdf_xml, const std::string& link, const std::string& source) {
  return parseUrdfOrThrow(urdf_xml, source)->getLink(link) != nullptr;
}

std::vector<double> jointEffortLimits(const std::string& urdf_xml, const std::string& base_link,
                                      const std::string& tip_link, const std::string& source) {
  chainFromUrdf(urdf_xml, base_link, tip_link, {}, source);  // the same checks and messages
  const urdf::ModelInterfaceSharedPtr model = parseUrdfOrThrow(urdf_xml, source);
  std::vector<double> effort_nm;
  for (const urdf::JointConstSharedPtr& j :
       urdfPathFromBase(*model, base_link, tip_link, source, "tip_link")) {
    if (j->type == urdf::Joint::FIXED) continue;
    const double effort = j->limits ? j->limits->effort : 0.0;
    effort_nm.push_back(std::isfinite(effort) && effort > 0.0 ? effort : 0.0);
  }
  return effort_nm;
}

UrdfOrigin urdfOriginOf(const Pose& X) {
  const auto triple = [](const Vec3& v) {
    return formatShortest(v.x()) + " " + formatShortest(v.y()) + " " + formatShortest(v.z());
  };
  return {triple(X.translation()), triple(lie::rpyFromRotation(X.linear()))};
}

std::string readTextFile(const std::string& path) {
  std::error_code ec;
  if (std::filesystem::is_directory(path, ec)) {
    throw InputError("is a folder; expected a file", path);
  }
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError("cannot open file for reading", path);
  std::ostringstream text;
  text << in.rdbuf();
  if (in.bad()) throw InputError("read error", path);
  return text.str();
}

KinematicChain chainFromUrdfFile(const std::string& path, const std::string& base_link,
                                 const std::string& tip_link,
                                 const std::vector<std::string>& attached_links) {
  return chainFromUrdf(readTextFile(path), base_link, tip_link, attached_links, path);
}

}  // namespace stepcal
