#pragma once
// A robot program as `stepcal correct` sees it: its targets (each a span of numbers in the source
// text, in the program's own units and conventions, converted to SI poses or joint angles), the
// tool and base frames the program holds, and the targets it cannot rewrite (Offs(…), a point
// computed at run time). The writer replaces only the numbers of the targets it is given new
// values for; every other byte (comments, folds, spacing, line endings, encoding) is kept.
// One reader+writer file per language (src/krl.cpp, rapid.cpp, urscript.cpp, fanuc_tp.cpp).
#include <cstddef>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "stepcal/common/types.hpp"

namespace stepcal::programs {

enum class Language { kKrl, kRapid, kUrScript, kFanucTp };

/// How a target's numbers are written back: the units and the orientation convention of the
/// language (KRL A,B,C and Fanuc W,P,R both as R = Rz·Ry·Rx; RAPID's quaternion w,x,y,z; UR's
/// rotation vector).
enum class Orientation {
  kZyxDeg,         ///< A, B, C: R = Rz(A)·Ry(B)·Rx(C), deg (KRL)
  kFixedXyzDeg,    ///< W, P, R: R = Rz(R)·Ry(P)·Rx(W), deg (Fanuc)
  kQuaternionWxyz, ///< q1..q4 = w, x, y, z (RAPID)
  kRotationVector  ///< rx, ry, rz, rad (URScript)
};

/// One number of the source text: where it is and how it was written.
struct NumberField {
  size_t begin = 0, end = 0;  ///< byte span in the source
  int decimals = 0;           ///< digits after the point as written (0: none)
};

enum class TargetKind { kCartesian, kJoint };

/// A literal target of the program.
struct Target {
  TargetKind kind = TargetKind::kCartesian;
  std::string name;       ///< the declared point's name (XP1, p10, P[3]); empty for an inline one
  int line = 0, column = 0;  ///< where its literal starts (1-based)
  /// kCartesian: X_, Y, Z and then the orientation's 3 or 4 numbers; kJoint: the robot's joints.
  std::vector<NumberField> fields;
  std::vector<double> written;  ///< the fields' values as written (file units)
  Pose X_FrameTcp = Pose::Identity();  ///< kCartesian: the TCP in its base/user frame, m
  JointVector q_rad;                   ///< kJoint: the joint angles, rad (URDF convention)
  std::string configuration;           ///< as written (S 6 T 27; [0,0,-1,1]; N U T, 0, 0, 0)
  /// The tool and frame the program gives the target: indices into Program::frames (-1: none
  /// named; the command line's or the flange/base then).
  int tool = -1, base = -1;
  /// The load in force at the target, an index into Program::loads: everything the flange
  /// carries (KRL $LOAD, Fanuc PAYLOAD[n], RAPID \TLoad, URScript set_payload). -1: none named,
  /// the tool's own load where the program gives one (RAPID tooldata), else unloaded.
  int load = -1;
  /// RAPID GripLoad: a payload the tool holds (its centre of gravity in the tool frame), added
  /// to the tool's load; an index into Program::loads, -1 none.
  int grip_load = -1;
  /// A declared point moved to under other loads than the first motion's (for which it is
  /// corrected): which, for its report line; empty when none.
  std::string other_loads;
};

/// A load the program names (LOAD_DATA[1], $LOAD, PAYLOAD[2], a RAPID loaddata, set_payload):
/// its mass and centre of gravity where the program gives them; named without values (KRL's
/// LOAD_DATA[n] of $config.dat, Fanuc's payload schedules) the command line gives them.
struct Load {
  std::string name;
  std::optional<double> mass_kg;  ///< nullopt: not in the program
  Vec3 p_CoG_m = Vec3::Zero();    ///< in the flange frame (a GripLoad's: in the tool frame), m
  /// Why the program's own values cannot be used (KUKA's M -1, the robot type's default load);
  /// empty when they are none or can.
  std::string without_values;
};

/// A tool, base or work object the program declares (TOOL_DATA[3], tooldata tGripper,
/// set_tcp(p[…]), or a Fanuc UT/UF number whose values the command line gives).
struct Frame {
  std::string name;
  std::optional<Pose> X;        ///< its pose (a tool: X_FlangeTcp; a base: X_BaseFrame), m
  double mass_kg = -1.0;        ///< a tool's load where the program gives it (RAPID tooldata)
  Vec3 p_CoG_m = Vec3::Zero();  ///< its centre of gravity in the flange frame, m
};

/// A target the program computes at run time (Offs(p10,0,0,50), RelTool, a FRAME composition):
/// reported, never corrected.
struct NotLiteral {
  int line = 0, column = 0;
  std::string text;  ///< the expression as written (cut to one line)
};

struct Program {
  Language language = Language::kKrl;
  Orientation orientation = Orientation::kZyxDeg;
  double file_units_per_m = 1000.0;  ///< mm (KRL, RAPID, TP) or m (URScript)
  double file_units_per_rad = 0.0;   ///< joint angles: deg (180/π) or rad (1)
  std::vector<Target> targets;
  std::vector<Frame> frames;
  std::vector<Load> loads;
  std::vector<NotLiteral> not_literals;
};

/// The index of the load named `name` (exact, or any case when `any_case`), added without
/// values when the program has none of that name yet.
int loadIndex(Program& program, const std::string& name, bool any_case = false);

/// A target's new value (the corrected pose in the same frame, or the corrected joints).
struct Replacement {
  size_t target = 0;  ///< index into Program::targets
  Pose X_FrameTcp = Pose::Identity();
  JointVector q_rad;
};

/// The language a file is in: from --format (krl, rapid, urscript, tp) or else from its
/// extension (.src/.dat, .mod/.prg/.sys, .script, .ls, any case); nullopt for stepcal's CSV.
/// Throws InputError for an unknown --format or extension it cannot tell.
std::optional<Language> languageOf(const std::string& path, const std::string& format);

std::string languageName(Language language);

/// Reads a program. Throws InputError with the file, line and column of anything it does not
/// fully understand (a truncated literal, an unknown field, an unbalanced bracket).
Program readProgram(Language language, std::string_view text, const std::string& path);

/// The text with every replacement's numbers written in place of the old ones (each number with
/// as many decimals as it had, and at least the language's resolution), every other byte kept.
std::string writeProgram(const Program& program, std::string_view text,
                         const std::vector<Replacement>& replacements);

/// Whether a replacement changes nothing a file can hold: position within 1e-4 mm, rotation
/// within 1e-7 rad, joints within 1e-7 rad.
bool unchangedWithinTolerance(const Target& target, const Replacement& replacement);

}  // namespace stepcal::programs
