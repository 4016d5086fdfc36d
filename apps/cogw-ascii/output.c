/* SPDX-License-Identifier: MIT */
/*
 * apps/cogw-ascii/output.c - a connection's output buffer: the answers
 * queued for the peer, written out by the loop (server.c) as its socket
 * takes them. The bottom of the program: it calls nothing above it.
 */
#include "apps/cogw-ascii/gateway.h"

#include <stdlib.h>
#include <string.h>

size_t conn_pending_out(const conn *c)
{
	return c->out_len - c->out_off;
}

bool conn_write(conn *c, const char *text, size_t len)
{
	if (c->dead)
		return false;
	if (c->out_len + len > c->out_cap) {
		if (c->out_off) { /* compact first */
			memmove(c->out, c->out + c->out_off, conn_pending_out(c));
			c->out_len -= c->out_off;
			c->out_off = 0;
		}
		if (c->out_len + len > c->out_cap) {
			size_t cap = c->out_cap ? c->out_cap : 4096;

			while (cap < c->out_len + len)
				cap *= 2;
			char *o = realloc(c->out, cap);

			if (!o) {
				c->dead = true;
				return false;
			}
			c->out = o;
			c->out_cap = cap;
		}
	}
	memcpy(c->out + c->out_len, text, len);
	c->out_len += len;
	c->kick = true;
	return true;
}
