// A daemon of message version 1 or 2, as a client sees it, for tests/python/test_stepcal.py:
// every request on STEPCAL_REQUEST gets that version's BAD_REQUEST refusal (correction_reply_v1_t
// or correction_reply_v2_t) on STEPCAL_REPLY, as a stepcal-runtime that predates message version
// 3 would send. Serves until killed; "serving" on stderr once subscribed.
//   old_daemon LCM_URL VERSION
#include <cstdio>
#include <string>
#include <vector>

#include <lcm/lcm.h>

#include "stepcal/service/channels.hpp"
#include "stepcal/service/reply.hpp"
#include "stepcal/service/request.hpp"

namespace {

struct OldDaemon {
  lcm_t* lcm;
  int version;
};

void onRequest(const lcm_recv_buf_t* rbuf, const char*, void* user) {
  using namespace stepcal::service;
  const auto* daemon = static_cast<const OldDaemon*>(user);
  Request request;
  decodeRequest(rbuf->data, int(rbuf->data_size), request);
  if (!request.request_id_known) return;
  std::vector<uint8_t> reply(static_cast<size_t>(replyBytes()));
  const int size = encodeOldVersionRefusal(daemon->version, request.request_id, 0, 0,
                                           reply.data(), int(reply.size()));
  lcm_publish(daemon->lcm, kReplyChannel, reply.data(), unsigned(size));
}

}  // namespace

int main(int argc, char** argv) {
  const std::string version = argc == 3 ? argv[2] : "";
  if (version != "1" && version != "2") {
    std::fprintf(stderr, "usage: old_daemon LCM_URL VERSION (1 or 2)\n");
    return 2;
  }
  lcm_t* lcm = lcm_create(argv[1]);
  if (lcm == nullptr) {
    std::fprintf(stderr, "old_daemon: LCM cannot open %s\n", argv[1]);
    return 2;
  }
  OldDaemon daemon{lcm, std::stoi(version)};
  lcm_subscribe(lcm, stepcal::service::kRequestChannel, &onRequest, &daemon);
  std::fprintf(stderr, "old_daemon: serving %s in message version %s\n", argv[1],
               version.c_str());
  while (lcm_handle(lcm) == 0) {
  }
  lcm_destroy(lcm);
  return 1;
}
