/* SPDX-License-Identifier: MIT */
/*
 * SDO client: the pool of requests shared by the channels, the gate that
 * shares the channels and servers with a second user (CiA 302-7 relay,
 * sdo_client_set_gate) and the raw leases of channels to that relay. It
 * decides what may start where and when (one transfer per server at a
 * time, a server that may still answer an aborted transfer settles
 * first); the transfers themselves are sdo_client_xfer.c's.
 */
#include <errno.h>
#include <string.h>

#include "core/sdo_client_int.h"

/* Another channel is talking to the same server right now? */
static bool target_busy(const struct sdo_client *cli, const struct cli_chan *self, uint32_t resp)
{
	for (uint8_t i = 0; i < cli->n; i++) {
		const struct cli_chan *o = &cli->ch[i];
		if (o != self && state_of(o) != CS_IDLE && o->cob_resp == resp)
			return true;
	}
	return false;
}

/* A transfer of ours with this server ended by our own abort before the
 * server answered its last request, and the server has not been quiet for
 * SETTLE_US since (each frame of it restarts the time, cli_rx): it may
 * still send that answer and the rest of the transfer. A relay would hand
 * them on as answers (it cannot tell them from the next requester's), and
 * so would a transfer of ours naming the same object if what is still
 * due is the initiate's answer (is_stale() tells only another object's
 * apart, or the old data phase's frames): both wait. */
#define SETTLE_US 100000u

static bool unsettled(const struct stale_xfer *e, uint32_t resp, uint64_t now_us)
{
	return e->valid && !e->answered && e->cob_resp == resp && now_us - e->at_us < SETTLE_US;
}

static bool settling(const struct sdo_client *cli, uint32_t resp, uint64_t now_us)
{
	for (uint8_t i = 0; i < cli->n; i++)
		if (unsettled(&cli->ch[i].ended, resp, now_us))
			return true;
	return false;
}

/* ---- the gate (sdo_client_set_gate) --------------------------------------- */

/* A refusal of the gate: whatever waits is tried again from the tick. */
#define GATE_RETRY_US 100000u

/* Whatever waits is tried again from the tick at `at` (or earlier). */
static void retry_at(struct sdo_client *cli, uint64_t at)
{
	if (at < cli->retry_us) {
		cli->retry_us = at;
		co_node_deadline_lower(cli->node, at);
	}
}

static void gate_refused(struct sdo_client *cli)
{
	if (cli->retry_us == CO_NO_DEADLINE)
		retry_at(cli, cli->node->now_us + GATE_RETRY_US);
}

/* The node-ID of a server on this bus the gate knows (580h + n), else 0. */
static uint8_t gate_server_of(uint32_t resp)
{
	return resp > SDO_COB_TX_BASE && resp <= SDO_COB_TX_BASE + 127u
		       ? (uint8_t)(resp - SDO_COB_TX_BASE)
		       : 0;
}

static bool srv_is_held(const struct sdo_client *cli, uint8_t n)
{
	return cli->srv_held[n / 64u] >> (n % 64u) & 1u;
}

/* May a request of the node's own start a transfer with this server? */
static bool gate_take_server(struct sdo_client *cli, uint32_t resp)
{
	uint8_t n = gate_server_of(resp);

	if (!cli->gate || !n || srv_is_held(cli, n))
		return true;
	if (!cli->gate(cli->gate_ctx, SDO_CLIENT_GATE_TAKE_SERVER, n)) {
		gate_refused(cli);
		return false;
	}
	cli->srv_held[n / 64u] |= 1ull << (n % 64u);
	return true;
}

/* May a request of the node's own use this (idle) channel? */
static bool gate_take_channel(struct cli_chan *ch)
{
	struct sdo_client *cli = ch->cli;

	if (!cli->gate || ch->gated_out)
		return true;
	if (!cli->gate(cli->gate_ctx, SDO_CLIENT_GATE_TAKE_CHANNEL, ch->num)) {
		gate_refused(cli);
		return false;
	}
	ch->gated_out = true;
	return true;
}

/* Something else talks to the server, or the gate lent it elsewhere? */
static bool server_blocked(struct sdo_client *cli, const struct cli_chan *self, uint32_t resp)
{
	return target_busy(cli, self, resp) || !gate_take_server(cli, resp);
}

/* Give the gate back what the node's own requests no longer use. */
void sdo_cli_gate_sync(struct sdo_client *cli)
{
	if (!cli->gate)
		return;
	for (uint8_t i = 0; i < cli->n; i++) {
		struct cli_chan *ch = &cli->ch[i];
		if (ch->gated_out && state_of(ch) == CS_IDLE && ch->q_len == 0) {
			ch->gated_out = false;
			cli->gate(cli->gate_ctx, SDO_CLIENT_GATE_FREE_CHANNEL, ch->num);
		}
	}
	for (uint8_t n = 1; n <= 127; n++) {
		uint32_t resp = SDO_COB_TX_BASE + n;
		if (!srv_is_held(cli, n) || target_busy(cli, NULL, resp) ||
		    settling(cli, resp, cli->node->now_us))
			continue;
		cli->srv_held[n / 64u] &= ~(1ull << (n % 64u));
		cli->gate(cli->gate_ctx, SDO_CLIENT_GATE_FREE_SERVER, n);
	}
	/* a server still settling goes back from the tick at its end, also
	 * when nothing else would tick the node (a transfer cancelled from
	 * outside) */
	co_node_deadline_lower(cli->node, sdo_cli_gate_next(cli));
}

/* May r start now? Not while a late answer about the same object may
 * still come, nor while another channel talks to its server or the gate
 * lent the server elsewhere. */
static bool may_start(struct sdo_client *cli, const struct cli_chan *self, const sdo_client_req *r)
{
	uint32_t resp = sdo_cli_cob_resp(r);
	uint64_t now_us = cli->node->now_us;

	for (uint8_t i = 0; i < cli->n; i++) {
		const struct stale_xfer *e = &cli->ch[i].ended;
		if (unsettled(e, resp, now_us) && !e->init_answered && e->index == r->index &&
		    e->sub == r->sub) {
			retry_at(cli, e->at_us + SETTLE_US);
			return false;
		}
	}
	return !server_blocked(cli, self, resp);
}

static void start(struct cli_chan *ch, const sdo_client_req *r)
{
	co_fsm_goto(&ch->fsm, sdo_cli_start_state(ch, r), node_of(ch)->now_us);
}

/* Start the head of the queue if the channel is idle and the target free. */
void sdo_cli_kick(struct cli_chan *ch)
{
	const sdo_client_req *r;

	if (state_of(ch) != CS_IDLE || ch->q_len == 0)
		return;
	r = &ch->q[ch->q_head];
	if (!may_start(ch->cli, ch, r) || !gate_take_channel(ch))
		return;
	sdo_client_req tmp = *r;
	ch->q_head = (uint16_t)((ch->q_head + 1) % node_of(ch)->cfg.sdo_client_queue_len);
	ch->q_len--;
	start(ch, &tmp);
}

/* Free for the pool: idle, nothing waiting in its own FIFO, and not lent
 * out by the gate. */
static struct cli_chan *free_channel(struct sdo_client *cli)
{
	for (uint8_t i = 0; i < cli->n; i++)
		if (state_of(&cli->ch[i]) == CS_IDLE && cli->ch[i].q_len == 0 &&
		    gate_take_channel(&cli->ch[i]))
			return &cli->ch[i];
	return NULL;
}

sdo_client_req *sdo_cli_pool_at(struct sdo_client *cli, uint16_t i)
{
	return &cli->pool[(cli->pool_head + i) % cli->node->cfg.sdo_client_pool_len];
}

void sdo_cli_pool_remove(struct sdo_client *cli, uint16_t i)
{
	if (i == 0) { /* the usual case: the oldest starts */
		cli->pool_head = (uint16_t)((cli->pool_head + 1) %
					    cli->node->cfg.sdo_client_pool_len);
		cli->pool_len--;
		return;
	}
	for (uint16_t j = i; j + 1 < cli->pool_len; j++)
		*sdo_cli_pool_at(cli, j) = *sdo_cli_pool_at(cli, (uint16_t)(j + 1));
	cli->pool_len--;
}

/* Start waiting pool requests, oldest first, on free channels. One whose
 * target is busy stays (and so do the later ones for that target, which
 * see the same busy target: per-target order holds). */
static void pool_kick(struct sdo_client *cli)
{
	uint16_t i = 0;

	while (i < cli->pool_len) {
		const sdo_client_req *r = sdo_cli_pool_at(cli, i);
		struct cli_chan *ch;

		if (!may_start(cli, NULL, r)) {
			i++;
			continue;
		}
		ch = free_channel(cli);
		if (!ch)
			return;
		sdo_client_req tmp = *r;
		sdo_cli_pool_remove(cli, i);
		start(ch, &tmp);
	}
}

void sdo_cli_kick_all(struct sdo_client *cli)
{
	for (uint8_t i = 0; i < cli->n; i++)
		sdo_cli_kick(&cli->ch[i]);
	pool_kick(cli);
	sdo_cli_gate_sync(cli);
}

bool sdo_cli_req_valid(const sdo_client_req *r)
{
	bool explicit_cob = r->cob_req && r->cob_resp;

	if (!explicit_cob && (r->node_id < 1 || r->node_id > 127))
		return false;
	if (r->mode > SDO_MODE_BLOCK)
		return false;
	if (!r->upload && r->size && !r->data && !r->src)
		return false;
	if (r->upload && r->buf && r->cap == 0 && r->size)
		return false;
	return true;
}

int sdo_client_pool_submit(co_node *node, const sdo_client_req *req, uint64_t now_us)
{
	struct sdo_client *cli = node->sdo_cli;

	if (!cli || !req || !sdo_cli_req_valid(req))
		return -EINVAL;
	node->now_us = now_us;
	if (req->no_wait) {
		struct cli_chan *ch = NULL;
		if (may_start(cli, NULL, req))
			ch = free_channel(cli);
		if (ch)
			start(ch, req);
		sdo_cli_gate_sync(cli);
		return ch ? 0 : -EBUSY;
	}
	if (cli->pool_len >= node->cfg.sdo_client_pool_len)
		return -ENOSPC;
	*sdo_cli_pool_at(cli, cli->pool_len) = *req;
	cli->pool_len++;
	pool_kick(cli);
	sdo_cli_gate_sync(cli);
	return 0;
}

/* ---- relay lease (CiA 302-7) ------------------------------------------------ */

/* When the gate wants the tick again: a refused request's retry, or the
 * end of a held server's settling time. */
uint64_t sdo_cli_gate_next(const struct sdo_client *cli)
{
	uint64_t next = cli->retry_us;

	for (uint8_t i = 0; i < cli->n; i++) {
		const struct stale_xfer *e = &cli->ch[i].ended;
		uint8_t n = gate_server_of(e->cob_resp);
		if (e->valid && !e->answered && n && srv_is_held(cli, n) &&
		    e->at_us + SETTLE_US > cli->node->now_us && e->at_us + SETTLE_US < next)
			next = e->at_us + SETTLE_US;
	}
	return next;
}

/* Lend ch raw toward r's server (the checks done). */
static int lease_bind(struct cli_chan *ch, const sdo_client_req *r, sdo_client_raw_fn fn, void *arg,
		      uint64_t now_us)
{
	co_node *node = node_of(ch);
	struct sdo_client *cli = ch->cli;
	uint32_t resp = sdo_cli_cob_resp(r);

	if (co_rx_move(node, ch->rx_handle, resp & CO_FRAME_EFF_MASK,
		       (resp & SDO_COB_EXT) ? CO_FRAME_EXT : 0) != 0)
		return -ENOSPC;
	/* the relay's frames to and from that server are not answers of ours */
	for (uint8_t i = 0; i < cli->n; i++)
		if (cli->ch[i].ended.cob_resp == resp)
			cli->ch[i].ended.valid = false;
	ch->cur = *r;
	ch->cob_req = sdo_cli_cob_req(r);
	ch->cob_resp = resp;
	ch->lease_fn = fn;
	ch->lease_arg = arg;
	co_fsm_goto(&ch->fsm, CS_LEASED, now_us);
	sdo_cli_show_target(ch, r);
	return ch->num;
}

int sdo_client_lease(co_node *node, uint8_t node_id, uint32_t cob_req, uint32_t cob_resp,
		     sdo_client_raw_fn fn, void *arg, uint64_t now_us)
{
	struct sdo_client *cli = node->sdo_cli;
	sdo_client_req r = { .node_id = node_id, .cob_req = cob_req, .cob_resp = cob_resp };
	struct cli_chan *ch;
	int rc;

	if (!cli || !fn || node_id < 1 || node_id > 127)
		return -EINVAL;
	node->now_us = now_us;
	if (settling(cli, sdo_cli_cob_resp(&r), now_us) ||
	    server_blocked(cli, NULL, sdo_cli_cob_resp(&r)))
		rc = -EALREADY;
	else if (!(ch = free_channel(cli)))
		rc = -EBUSY;
	else
		rc = lease_bind(ch, &r, fn, arg, now_us);
	sdo_cli_gate_sync(cli);
	return rc;
}

int sdo_client_lease_channel(co_node *node, uint8_t channel, uint8_t node_id, sdo_client_raw_fn fn,
			     void *arg, uint64_t now_us)
{
	struct sdo_client *cli = node->sdo_cli;
	sdo_client_req r = { .node_id = node_id };
	struct cli_chan *ch;
	int rc;

	if (!cli || !fn || node_id < 1 || node_id > 127 || channel >= cli->n)
		return -EINVAL;
	node->now_us = now_us;
	ch = &cli->ch[channel];
	if (state_of(ch) != CS_IDLE || ch->gated_out)
		return -EBUSY;
	if (target_busy(cli, NULL, sdo_cli_cob_resp(&r)) ||
	    settling(cli, sdo_cli_cob_resp(&r), now_us))
		return -EALREADY;
	rc = lease_bind(ch, &r, fn, arg, now_us);
	if (rc >= 0)
		ch->gated_out = true; /* given back at its end (sdo_cli_gate_sync) */
	return rc;
}

static struct cli_chan *leased(co_node *node, uint8_t channel)
{
	struct sdo_client *cli = node->sdo_cli;

	if (!cli || channel >= cli->n || state_of(&cli->ch[channel]) != CS_LEASED)
		return NULL;
	return &cli->ch[channel];
}

int sdo_client_lease_move(co_node *node, uint8_t channel, uint8_t node_id, uint64_t now_us)
{
	struct cli_chan *ch = leased(node, channel);
	sdo_client_req r = { .node_id = node_id };
	int rc;

	if (!ch)
		return -ENOENT;
	if (node_id < 1 || node_id > 127)
		return -EINVAL;
	node->now_us = now_us;
	if (target_busy(ch->cli, ch, sdo_cli_cob_resp(&r)) ||
	    settling(ch->cli, sdo_cli_cob_resp(&r), now_us))
		return -EALREADY;
	rc = lease_bind(ch, &r, ch->lease_fn, ch->lease_arg, now_us);
	if (rc < 0)
		return rc;
	sdo_cli_kick_all(ch->cli);
	return 0;
}

int sdo_client_lease_send(co_node *node, uint8_t channel, const uint8_t d[8])
{
	struct cli_chan *ch = leased(node, channel);

	if (!ch)
		return -ENOENT;
	sdo_cli_tx(ch, d);
	return 0;
}

int sdo_client_lease_end(co_node *node, uint8_t channel, uint64_t now_us)
{
	struct cli_chan *ch = leased(node, channel);

	if (!ch)
		return -ENOENT;
	node->now_us = now_us;
	co_fsm_goto(&ch->fsm, CS_IDLE, now_us); /* nothing to confirm */
	ch->lease_fn = NULL;
	co_rx_disable(node, ch->rx_handle);
	sdo_cli_kick_all(ch->cli);
	return 0;
}

void sdo_client_set_gate(co_node *node, sdo_client_gate_fn fn, void *ctx)
{
	struct sdo_client *cli = node->sdo_cli;

	if (!cli)
		return;
	cli->gate = fn;
	cli->gate_ctx = ctx;
	cli->srv_held[0] = cli->srv_held[1] = 0;
	cli->retry_us = CO_NO_DEADLINE;
	for (uint8_t i = 0; i < cli->n; i++) {
		struct cli_chan *ch = &cli->ch[i];
		uint8_t n = gate_server_of(ch->cob_resp);
		ch->gated_out = fn != NULL; /* what is free is announced by gate_sync */
		if (fn && n && state_of(ch) != CS_IDLE && fn(ctx, SDO_CLIENT_GATE_TAKE_SERVER, n))
			cli->srv_held[n / 64u] |= 1ull << (n % 64u);
	}
	sdo_cli_gate_sync(cli);
}

void sdo_client_gate_kick(co_node *node, uint64_t now_us)
{
	struct sdo_client *cli = node->sdo_cli;

	/* nothing refused waits for a retry: the lease's end kicked the rest */
	if (!cli || !cli->gate || cli->retry_us == CO_NO_DEADLINE)
		return;
	node->now_us = now_us;
	cli->retry_us = CO_NO_DEADLINE;
	sdo_cli_kick_all(cli);
}

unsigned sdo_client_pool_waiting(const co_node *node)
{
	return node->sdo_cli ? node->sdo_cli->pool_len : 0;
}
