/* SPDX-License-Identifier: MIT */
/*
 * mailbox/server_answer.c - the line's answer to a request
 * (mbx_server_respond): one message, or a stream (server_xfer.c); the
 * transfer slot that held the request's data is given back here.
 */
#include "mailbox/server_int.h"

#include <errno.h>

static int respond(mbx_server *srv, const mbx_reply_to *to, int status, uint32_t abort,
		   const void *payload, size_t len)
{
	mbx_client *c;

	c = srv_client_find(srv, to->client);
	if (!c)
		return -ENOENT;
	if (c->outstanding)
		c->outstanding--;
	if (to->flags & MBX_F_NO_REPLY)
		return 0;
	if (len <= srv_chunk_size(c)) {
		int rc = srv_send_status(srv, c, to->code, to->corr, status, abort, payload, len);

		return rc == -EPIPE ? -ENOENT : rc;
	}
	return srv_stream_answer(srv, c, to, status, abort, payload, len);
}

int mbx_server_respond(mbx_server *srv, const mbx_reply_to *to, int status, uint32_t abort,
		       const void *payload, size_t len)
{
	mbx_xfer *x, *held = NULL;
	int rc;

	if (to->slot && to->slot <= srv->cfg.xfer_slots) {
		x = &srv->xfers[to->slot - 1];
		if (x->st == XS_HELD && x->client == to->client && x->corr == to->corr) {
			/* the slot is free again, but payload may live in
			 * its buffer: its pages go back once it is copied */
			held = x;
			srv_xfer_end(srv, x, true);
		}
	}
	rc = respond(srv, to, status, abort, payload, len);
	if (held && held->st == XS_FREE && held->touched > MBX_BUFFER_KEEP) {
		mbx_buffer_release(held->buf, held->touched);
		held->touched = MBX_BUFFER_KEEP;
	}
	return rc;
}
