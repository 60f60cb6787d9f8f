# StepcalVcan.cmake: ctest tests that need SocketCAN (vcan0), run through tests/system/vcan_run.sh.
#
#   include(cmake/StepcalVcan.cmake)
#   stepcal_add_vcan_test(NAME <name> COMMAND <cmd> [args...]
#                         [TIMEOUT <seconds>] [WRITABLE <dir>...]
#                         [WORKING_DIRECTORY <dir>] [LABELS <label>...])
#
# Registers test <name> that runs <cmd> [args...] via tests/system/vcan_run.sh: directly on a host with
# vcan0, otherwise in the small qemu VM with vcan0 up (see docs/vcan.md).
#   COMMAND      the command; an executable target's name as first word becomes its path.
#   TIMEOUT      seconds the command may take, default 300: vcan_run.sh --timeout (exit 124,
#                "timeout" on stderr); the ctest TIMEOUT is 120 s more, for the VM's boot and a
#                first run's one-time kernel download, so vcan_run.sh's message comes first.
#   WRITABLE     directories the command writes results to that must survive (vcan_run.sh
#                --writable; created if missing). In the VM everything else in the host's /
#                is read-only, and /tmp, /var/tmp, /run, /dev/shm are writable but thrown away.
#   WORKING_DIRECTORY  as for add_test (default: the current binary dir); the VM keeps it.
#   LABELS       more labels; "vcan" is always set, so `ctest -L vcan` / `-LE vcan` select them.
# Every such test holds RESOURCE_LOCK stepcal_vm: two VMs never boot at once (2 cores), and two
# tests never share vcan0 at once on a host that has it.
include_guard(GLOBAL)

# Captured here: inside the function CMAKE_CURRENT_LIST_DIR is the caller's directory.
set(STEPCAL_VCAN_RUN "${CMAKE_CURRENT_LIST_DIR}/../tests/system/vcan_run.sh")
cmake_path(NORMAL_PATH STEPCAL_VCAN_RUN)

function(stepcal_add_vcan_test)
  cmake_parse_arguments(PARSE_ARGV 0 arg "" "NAME;TIMEOUT;WORKING_DIRECTORY"
                        "COMMAND;WRITABLE;LABELS")
  if(arg_UNPARSED_ARGUMENTS)
    message(FATAL_ERROR "stepcal_add_vcan_test: unknown arguments: ${arg_UNPARSED_ARGUMENTS}")
  endif()
  if(NOT arg_NAME OR NOT arg_COMMAND)
    message(FATAL_ERROR "stepcal_add_vcan_test: NAME and COMMAND are required")
  endif()
  if(NOT DEFINED arg_TIMEOUT)
    set(arg_TIMEOUT 300)
  endif()
  if(NOT arg_TIMEOUT MATCHES "^[1-9][0-9]*$")
    message(FATAL_ERROR "stepcal_add_vcan_test(${arg_NAME}): TIMEOUT must be whole seconds > 0")
  endif()

  # add_test maps a target name to its file only as the first word, which is vcan_run.sh here.
  list(POP_FRONT arg_COMMAND command)
  if(TARGET "${command}")
    get_target_property(type "${command}" TYPE)
    if(type STREQUAL "EXECUTABLE")
      set(command "$<TARGET_FILE:${command}>")
    endif()
  endif()

  set(run_args --timeout ${arg_TIMEOUT})
  foreach(dir IN LISTS arg_WRITABLE)
    list(APPEND run_args --writable "${dir}")
  endforeach()
  set(workdir)
  if(arg_WORKING_DIRECTORY)
    set(workdir WORKING_DIRECTORY "${arg_WORKING_DIRECTORY}")
  endif()
  add_test(NAME "${arg_NAME}"
           COMMAND "${STEPCAL_VCAN_RUN}" ${run_args} -- "${command}" ${arg_COMMAND}
           ${workdir})
  math(EXPR ctest_timeout "${arg_TIMEOUT} + 120")
  set(labels vcan ${arg_LABELS})
  set_tests_properties("${arg_NAME}" PROPERTIES
    LABELS "${labels}"
    TIMEOUT ${ctest_timeout}
    RESOURCE_LOCK stepcal_vm)
endfunction()
