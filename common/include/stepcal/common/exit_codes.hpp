// Exit statuses shared by every stepcal command (stepcal and its subcommands, stepcal-client,
// stepcal-runtime): a script or a cell controller tells from the status alone whether the work
// was done. README.md ("Exit status") and docs/runtime.md list them too.
#pragma once

namespace stepcal::exit_code {

inline constexpr int kDone = 0;          ///< everything asked was done
inline constexpr int kFailed = 1;        ///< another failure (a goal missed, a torn answer)
inline constexpr int kBadInput = 2;      ///< bad input or usage: nothing was done
inline constexpr int kDoneInPart = 3;    ///< some targets or requests were not corrected (status not OK)
inline constexpr int kNoService = 4;     ///< no reply in time, replies refused by the key check, or a
                                         ///< command the daemon refused or did not confirm

/// The table for every command's --help (CLI11's footer).
inline constexpr const char* kHelpFooter =
    "Exit status: 0 everything done; 1 other failure; 2 bad input or usage (nothing done);\n"
    "3 done in part (some targets or requests not corrected: status not OK, or no reply);\n"
    "4 service unavailable (no reply in time, replies refused by the key check, or a sensor\n"
    "command refused or not confirmed).";

}  // namespace stepcal::exit_code
