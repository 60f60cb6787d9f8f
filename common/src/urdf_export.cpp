// A model file's calibrated geometry written back into the robot's URDF (see urdf_export.hpp).
#include "stepcal/common/urdf_export.hpp"

#include <tinyxml.h>

#include <cmath>
#include <map>
#include <set>

#include "stepcal/common/error.hpp"
#include "stepcal/common/lie.hpp"
#include "stepcal/common/text_number.hpp"
#include "stepcal/common/urdf.hpp"
#include "urdf_model.hpp"

namespace stepcal {
namespace {

// Largest |ω| − 1 and pitch ω·v (m/rad) of a twist written as a URDF revolute joint: what the
// URDF's joint then does differently is below 1e-11 m and rad over ±10 rad.
constexpr double kTwistTolerance = 1e-12;
// Largest difference (m, rad) between the URDF's nominal chain and the model's.
constexpr double kSameRobotTolerance = 1e-9;

Pose translation(const Vec3& p_m) {
  Pose X = Pose::Identity();
  X.translation() = p_m;
  return X;
}

// The point of the joint's rotation line nearest its frame's origin, in that frame (m); refuses
// a twist a URDF revolute joint cannot turn like.
Vec3 axisPointOf(const ChainJoint& joint, const std::string& model_source) {
  const Vec3 v = joint.twist_Local.head<3>(), w = joint.twist_Local.tail<3>();
  if (!(std::abs(w.norm() - 1.0) <= kTwistTolerance)) {
    throw InputError("joint '" + joint.name + "': twist rotation axis has norm " +
                         formatShortest(w.norm()) + "; expected 1 within " +
                         formatShortest(kTwistTolerance) +
                         ", as a URDF revolute joint turns by exactly its angle",
                     model_source);
  }
  const double pitch_m_per_rad = w.dot(v);
  if (!(std::abs(pitch_m_per_rad) <= kTwistTolerance)) {
    throw InputError("joint '" + joint.name + "': twist has pitch ω·v = " +
                         formatShortest(pitch_m_per_rad) + " m/rad; expected 0 within " +
                         formatShortest(kTwistTolerance) +
                         ", as a URDF revolute joint does not slide along its axis; hint: "
                         "export a model of `stepcal calibrate`, whose twists are pure rotations",
                     model_source);
  }
  return w.cross(v);
}

// Refuses a URDF whose chain base_link → tip_link is not the model's nominal one.
void checkSameRobot(const KinematicChain& chain_Urdf, const CalibratedModel& model,
                    const RobotDescription& robot) {
  const KinematicChain& nominal = model.nominal_Base;
  const std::string hint =
      "; expected the robot description the model was calibrated from; hint: use the campaign "
      "the model was calibrated on";
  if (chain_Urdf.dof() != nominal.dof() || chain_Urdf.dof() != model.chain_Tracker.dof()) {
    throw InputError("the chain '" + robot.base_link + "' → '" + robot.tip_link + "' has " +
                         std::to_string(chain_Urdf.dof()) + " revolute joints, the model " +
                         std::to_string(model.chain_Tracker.dof()) + hint,
                     robot.source);
  }
  for (int k = 0; k <= nominal.dof(); ++k) {
    const std::string what =
        k < nominal.dof() ? "joint '" + nominal.joints()[static_cast<size_t>(k)].name + "'"
                          : "the tip '" + robot.tip_link + "'";
    if (k < nominal.dof()) {
      const ChainJoint& a = chain_Urdf.joints()[static_cast<size_t>(k)];
      const ChainJoint& b = nominal.joints()[static_cast<size_t>(k)];
      if (a.name != b.name) {
        throw InputError("joint " + std::to_string(k + 1) + " of the chain is '" + a.name +
                             "', the model's '" + b.name + "'" + hint,
                         robot.source);
      }
      if (!((a.twist_Local - b.twist_Local).norm() <= kSameRobotTolerance)) {
        throw InputError(what + " has another axis than in the model's nominal chain" + hint,
                         robot.source);
      }
    }
    const Pose& X_a = chain_Urdf.initialPose(k);
    const Pose& X_b = nominal.initialPose(k);
    const double distance_m = (X_a.translation() - X_b.translation()).norm();
    const double angle_rad = lie::angleBetween(X_a.linear(), X_b.linear());
    if (!(distance_m <= kSameRobotTolerance && angle_rad <= kSameRobotTolerance)) {
      throw InputError(what + ": the pose before it differs from the model's nominal chain by " +
                           formatShortest(distance_m) + " m and " + formatShortest(angle_rad) +
                           " rad" + hint,
                       robot.source);
    }
  }
}

// The element's first child element called name, added when there is none.
TiXmlElement* childElement(TiXmlElement& parent, const char* name) {
  TiXmlElement* child = parent.FirstChildElement(name);
  if (child != nullptr) return child;
  return parent.InsertEndChild(TiXmlElement(name))->ToElement();
}

void setOrigin(TiXmlElement& element, const Pose& X) {
  const UrdfOrigin origin = urdfOriginOf(X);
  TiXmlElement* o = childElement(element, "origin");
  o->SetAttribute("xyz", origin.xyz);
  o->SetAttribute("rpy", origin.rpy);
}

void addLink(TiXmlElement& robot, const std::string& name) {
  TiXmlElement link("link");
  link.SetAttribute("name", name);
  robot.InsertEndChild(link);
}

void addFixedJoint(TiXmlElement& robot, const std::string& name, const std::string& parent,
                   const std::string& child, const Pose& X_ParentChild) {
  TiXmlElement joint("joint");
  joint.SetAttribute("name", name);
  joint.SetAttribute("type", "fixed");
  childElement(joint, "parent")->SetAttribute("link", parent);
  childElement(joint, "child")->SetAttribute("link", child);
  setOrigin(joint, X_ParentChild);
  robot.InsertEndChild(joint);
}

// The robot's <link> or <joint> elements by name.
std::map<std::string, TiXmlElement*> elementsByName(TiXmlElement& robot, const char* tag) {
  std::map<std::string, TiXmlElement*> out;
  for (TiXmlElement* e = robot.FirstChildElement(tag); e != nullptr;
       e = e->NextSiblingElement(tag)) {
    if (const char* name = e->Attribute("name")) out[name] = e;
  }
  return out;
}

void collectSubtree(const urdf::Link& link, std::set<std::string>& names) {
  names.insert(link.name);
  for (const urdf::LinkSharedPtr& child : link.child_links) collectSubtree(*child, names);
}

// Refuses a name the export adds when the robot description already uses it.
void claimName(std::set<std::string>& used, const std::string& name, const char* kind,
               const std::string& source) {
  if (!used.insert(name).second) {
    throw InputError("the robot description already has a " + std::string(kind) + " '" + name +
                         "'; expected it free for the export's own " + kind +
                         "; hint: rename it in the URDF",
                     source);
  }
}

}  // namespace

CalibratedUrdf calibratedUrdf(const CalibratedModel& model, const std::string& model_source,
                              const RobotDescription& robot) {
  if (!model.mechanisms.empty()) {
    throw InputError("an extended model (" + std::to_string(model.mechanisms.size()) +
                         " mechanisms of `stepcal diagnose`): its chain was fitted together with "
                         "the mechanisms and alone is no model of the robot; expected a model of "
                         "`stepcal calibrate`; hint: export the model diagnose started from",
                     model_source);
  }
  const KinematicChain& chain = model.chain_Tracker;
  checkSameRobot(chainFromUrdf(robot.urdf_xml, robot.base_link, robot.tip_link, {}, robot.source),
                 model, robot);
  std::vector<Vec3> axis_points_m;
  for (const ChainJoint& joint : chain.joints()) {
    axis_points_m.push_back(axisPointOf(joint, model_source));
  }

  const urdf::ModelInterfaceSharedPtr parsed = parseUrdfOrThrow(robot.urdf_xml, robot.source);
  TiXmlDocument document;
  document.Parse(robot.urdf_xml.c_str());
  TiXmlElement* robot_element = document.RootElement();
  STEPCAL_INVARIANT(!document.Error() && robot_element != nullptr,
                    "TinyXML reads what urdfdom, which parses with it, accepted");
  std::map<std::string, TiXmlElement*> links = elementsByName(*robot_element, "link");
  std::map<std::string, TiXmlElement*> joints = elementsByName(*robot_element, "joint");

  CalibratedUrdf out;
  std::set<std::string> kept_links;
  collectSubtree(*parsed->getLink(robot.base_link), kept_links);
  for (const auto& [name, element] : links) {
    if (kept_links.count(name) != 0) continue;
    out.dropped_links.push_back(name);
    robot_element->RemoveChild(element);
  }
  std::set<std::string> link_names = kept_links, joint_names;
  for (const auto& [name, element] : joints) {
    const urdf::JointConstSharedPtr joint = parsed->getJoint(name);
    const std::string& child = joint->child_link_name;
    if (kept_links.count(child) != 0 && child != robot.base_link) {
      joint_names.insert(name);
    } else {
      robot_element->RemoveChild(element);
    }
  }

  // Walk base_link → tip_link: X_FrameLink is the current link's pose in the last chain frame
  // (the nominal fixed joints since), which each calibrated origin is taken relative to.
  Pose X_FrameLink = Pose::Identity();
  size_t k = 0;
  for (const urdf::JointConstSharedPtr& j :
       urdfPathFromBase(*parsed, robot.base_link, robot.tip_link, robot.source, "tip_link")) {
    if (j->type == urdf::Joint::FIXED) {
      X_FrameLink = X_FrameLink * poseFromUrdf(j->parent_to_joint_origin_transform);
      continue;
    }
    // X_FrameJoint = T_{k,k+1}(0); T_{0,1}(0) starts in the tracker frame, and the world
    // joint carries X_TrackerBase.
    const Pose X_FrameJoint = k == 0 ? Pose(model.X_TrackerBase.inverse() * chain.initialPose(0))
                                     : chain.initialPose(static_cast<int>(k));
    const Vec3& p_AxisInJoint_m = axis_points_m[k];
    TiXmlElement& joint = *joints.at(j->name);
    setOrigin(joint, X_FrameLink.inverse() * X_FrameJoint * translation(p_AxisInJoint_m));
    const Vec3 axis = chain.joints()[k].twist_Local.tail<3>();
    childElement(joint, "axis")->SetAttribute(
        "xyz", formatShortest(axis.x()) + " " + formatShortest(axis.y()) + " " +
                   formatShortest(axis.z()));
    if (!p_AxisInJoint_m.isZero(0.0)) {
      // URDF turns a joint about a line through the joint frame's origin: the chain's frame,
      // off that line, is one fixed joint further.
      const std::string on_axis = j->child_link_name + "_on_axis";
      const std::string offset_joint = on_axis + "-" + j->child_link_name;
      claimName(link_names, on_axis, "link", robot.source);
      claimName(joint_names, offset_joint, "joint", robot.source);
      childElement(joint, "child")->SetAttribute("link", on_axis);
      addLink(*robot_element, on_axis);
      addFixedJoint(*robot_element, offset_joint, on_axis, j->child_link_name,
                    translation(-p_AxisInJoint_m));
    }
    X_FrameLink = Pose::Identity();
    ++k;
  }

  const std::string world_joint = std::string(kUrdfWorldLink) + "-" + robot.base_link;
  const std::string tool_joint = robot.tip_link + "-" + kUrdfToolLink;
  claimName(link_names, kUrdfWorldLink, "link", robot.source);
  claimName(link_names, kUrdfToolLink, "link", robot.source);
  claimName(joint_names, world_joint, "joint", robot.source);
  claimName(joint_names, tool_joint, "joint", robot.source);
  addLink(*robot_element, kUrdfWorldLink);
  addFixedJoint(*robot_element, world_joint, kUrdfWorldLink, robot.base_link, model.X_TrackerBase);
  addLink(*robot_element, kUrdfToolLink);
  addFixedJoint(*robot_element, tool_joint, robot.tip_link, kUrdfToolLink,
                X_FrameLink.inverse() * chain.initialPose(chain.dof()));

  const ModelProvenance& provenance = model.provenance;
  const TiXmlComment note(
      (" Calibrated geometry from a stepcal model (campaign hash " + provenance.campaign_hash +
       ", trained " + provenance.created_utc + "): revolute joint origins and axes are the "
       "calibrated ones; 'world' is the tracker frame, 'tool' the calibrated " + robot.tip_link +
       ". A URDF cannot carry the model's compliance or GPR. ")
          .c_str());
  robot_element->Parent()->InsertBeforeChild(robot_element, note);
  TiXmlPrinter printer;
  printer.SetIndent("  ");
  document.Accept(&printer);
  out.urdf_xml = printer.Str();
  return out;
}

}  // namespace stepcal
