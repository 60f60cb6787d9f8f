// A daemon of message version 1, as a client sees it, for tests/python/test_stepcal.py: every
// request on STEPCAL_REQUEST gets the version-1 BAD_REQUEST refusal (correction_reply_v1_t) on
// STEPCAL_REPLY, as a stepcal-runtime that predates message version 2 would send. Serves until
// killed; "serving" on stderr once subscribed.
//   old_daemon LCM_URL
#include <cstdio>
#include <vector>

#include <lcm/lcm.h>

#include "stepcal/service/channels.hpp"
#include "stepcal/service/reply.hpp"
#include "stepcal/service/request.hpp"

namespace {

void onRequest(const lcm_recv_buf_t* rbuf, const char*, void* user) {
  using namespace stepcal::service;
  Request request;
  decodeRequest(rbuf->data, int(rbuf->data_size), request);
  if (!request.request_id_known) return;
  std::vector<uint8_t> reply(static_cast<size_t>(replyBytes()));
  const int size =
      encodeOldVersionRefusal(request.request_id, 0, 0, reply.data(), int(reply.size()));
  lcm_publish(static_cast<lcm_t*>(user), kReplyChannel, reply.data(), unsigned(size));
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 2) {
    std::fprintf(stderr, "usage: old_daemon LCM_URL\n");
    return 2;
  }
  lcm_t* lcm = lcm_create(argv[1]);
  if (lcm == nullptr) {
    std::fprintf(stderr, "old_daemon: LCM cannot open %s\n", argv[1]);
    return 2;
  }
  lcm_subscribe(lcm, stepcal::service::kRequestChannel, &onRequest, lcm);
  std::fprintf(stderr, "old_daemon: serving %s\n", argv[1]);
  while (lcm_handle(lcm) == 0) {
  }
  lcm_destroy(lcm);
  return 1;
}
