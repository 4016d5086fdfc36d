/* SPDX-License-Identifier: MIT */
/*
 * LSS slave (CiA 305). One receiver on 7E5h; every command specifier has
 * its own small handler, picked from a table. Answers go out on 7E4h.
 *
 * Why some choices:
 * - Switch selective and identify remote are sequences of frames. The
 *   slave keeps how far the sequence has matched; any frame of the
 *   sequence that does not match (or comes out of order) starts it over,
 *   so a master that gave up half-way leaves no stale partial match.
 * - Fastscan is answered only by slaves in waiting state without a node-ID
 *   (active and pending both 255): a slave that has just been given an id
 *   must drop out of the next scan, or the master would find it again.
 * - The automatic reset communication of a slave that started without a
 *   node-ID runs at the end of the switch-to-waiting handler, after the
 *   state change has been reported, so that the application sees
 *   "waiting" before the node-ID change.
 */
#include <errno.h>
#include <stdlib.h>

#include "core/co_internal.h"
#include "core/lss_slave.h"

struct lss_slave {
	co_node *node;
	int rx;
	lss_state state;
	uint8_t active_id;
	uint8_t pending_id;
	uint8_t persistent_id;
	bool constant_id;
	bool bt_valid; /* a bit timing was configured */
	uint8_t bt_table;
	uint8_t bt_index;
	uint8_t sel_matched;   /* switch selective: fields matched so far */
	uint8_t ident_matched; /* identify remote: frames matched so far */
	uint8_t fs_pos;        /* Fastscan: LSSSub this slave listens to */
	const lss_slave_hooks *hooks;
	void *hook_ctx;
};

typedef void (*lss_slave_handler)(struct lss_slave *s, const co_frame *f, uint64_t now_us);

/* ---- helpers --------------------------------------------------------------- */

static uint32_t identity(const struct lss_slave *s, unsigned field)
{
	uint32_t v = 0;

	/* A missing 1018h sub reads as 0 (CiA 301 makes only sub 1 mandatory;
	 * LSS needs all four, so such a device can only be reached by id 0). */
	(void)co_od_get_u32(co_node_od(s->node), 0x1018, (uint8_t)(field + 1), &v);
	return v;
}

static void answer(struct lss_slave *s, uint8_t cs, const uint8_t *payload, unsigned n)
{
	co_frame f;

	co_frame_init(&f, LSS_COBID_SLAVE, 8);
	f.data[0] = cs;
	for (unsigned i = 0; i < n && i < 7; i++)
		f.data[1 + i] = payload[i];
	(void)co_node_send(s->node, &f); /* failures are counted by the core */
}

static void answer_u32(struct lss_slave *s, uint8_t cs, uint32_t v)
{
	uint8_t p[4];

	co_put_le32(p, v);
	answer(s, cs, p, 4);
}

static void answer_code(struct lss_slave *s, uint8_t cs, uint8_t code, uint8_t spec)
{
	uint8_t p[2] = { code, code == LSS_EC_SPECIFIC ? spec : 0 };

	answer(s, cs, p, 2);
}

static void emit(struct lss_slave *s, co_event_kind kind, uint16_t delay_ms)
{
	co_event ev = { .kind = kind };

	ev.u.lss_slave.state = (uint8_t)s->state;
	ev.u.lss_slave.active_id = s->active_id;
	ev.u.lss_slave.pending_id = s->pending_id;
	ev.u.lss_slave.persistent_id = s->persistent_id;
	ev.u.lss_slave.bt_table = s->bt_table;
	ev.u.lss_slave.bt_index = s->bt_index;
	ev.u.lss_slave.bt_valid = s->bt_valid;
	ev.u.lss_slave.delay_ms = delay_ms;
	co_node_emit(s->node, &ev);
}

static bool unconfigured(const struct lss_slave *s)
{
	return s->active_id == LSS_NODE_ID_UNCONFIGURED &&
	       s->pending_id == LSS_NODE_ID_UNCONFIGURED;
}

static bool node_id_valid(uint8_t id)
{
	return (id >= 1 && id <= 127) || id == LSS_NODE_ID_UNCONFIGURED;
}

static void set_state(struct lss_slave *s, lss_state st)
{
	s->sel_matched = 0;
	if (s->state == st)
		return;
	s->state = st;
	emit(s, CO_EV_LSS_SLAVE_STATE, 0);
}

/* ---- switch state ---------------------------------------------------------- */

static void on_switch_global(struct lss_slave *s, const co_frame *f, uint64_t now_us)
{
	uint8_t mode = f->data[1];
	bool auto_reset;

	if (mode == LSS_STATE_CONFIGURATION) {
		set_state(s, LSS_STATE_CONFIGURATION);
		return;
	}
	if (mode != LSS_STATE_WAITING)
		return; /* reserved mode: ignore */
	auto_reset = s->state == LSS_STATE_CONFIGURATION &&
		     s->active_id == LSS_NODE_ID_UNCONFIGURED &&
		     s->pending_id != LSS_NODE_ID_UNCONFIGURED;
	set_state(s, LSS_STATE_WAITING);
	/* CiA 305: a slave without a node-ID that got one applies it on its
	 * own when it leaves configuration state (no NMT master would address
	 * an unconfigured node). */
	if (auto_reset)
		co_node_reset_comm(s->node, now_us);
}

static void on_switch_selective(struct lss_slave *s, const co_frame *f, uint64_t now_us)
{
	unsigned field = (unsigned)(f->data[0] - LSS_CS_SWITCH_SEL_VENDOR);

	(void)now_us;
	if (s->state != LSS_STATE_WAITING)
		return;
	if (field != s->sel_matched || co_get_le32(&f->data[1]) != identity(s, field)) {
		/* A vendor frame always starts a new sequence. */
		s->sel_matched = field == 0 && co_get_le32(&f->data[1]) == identity(s, 0);
		return;
	}
	if (++s->sel_matched < LSS_ID_COUNT)
		return;
	set_state(s, LSS_STATE_CONFIGURATION);
	answer(s, LSS_CS_SWITCH_SEL_RESPONSE, NULL, 0);
}

/* ---- configuration services (configuration state only) --------------------- */

static void on_config_node_id(struct lss_slave *s, const co_frame *f, uint64_t now_us)
{
	uint8_t id = f->data[1];

	(void)now_us;
	if (!node_id_valid(id)) {
		answer_code(s, LSS_CS_CONFIG_NODE_ID, LSS_EC_NODE_ID_RANGE, 0);
		return;
	}
	answer_code(s, LSS_CS_CONFIG_NODE_ID, LSS_EC_OK, 0);
	if (s->pending_id != id) {
		s->pending_id = id;
		emit(s, CO_EV_LSS_SLAVE_NODE_ID, 0);
	}
}

static void on_config_bit_timing(struct lss_slave *s, const co_frame *f, uint64_t now_us)
{
	uint8_t table = f->data[1], index = f->data[2], spec = 0, ec;

	(void)now_us;
	if (s->hooks && s->hooks->check_bit_timing)
		ec = s->hooks->check_bit_timing(s->hook_ctx, table, index, &spec);
	else
		ec = table == LSS_BT_TABLE_CIA && lss_bit_rate_kbit(index)
			     ? LSS_EC_OK
			     : LSS_EC_BIT_TIMING_UNSUPP;
	if (ec == LSS_EC_OK) {
		s->bt_valid = true;
		s->bt_table = table;
		s->bt_index = index;
	}
	answer_code(s, LSS_CS_CONFIG_BIT_TIMING, ec, spec);
}

static void on_activate_bit_timing(struct lss_slave *s, const co_frame *f, uint64_t now_us)
{
	(void)now_us;
	/* Unconfirmed. Without a configured bit timing there is nothing to
	 * switch to. The application switches after delay_ms and stays
	 * silent for another delay_ms (CiA 305). */
	if (s->bt_valid)
		emit(s, CO_EV_LSS_SLAVE_BIT_TIMING, co_get_le16(&f->data[1]));
}

static void on_store(struct lss_slave *s, const co_frame *f, uint64_t now_us)
{
	uint8_t spec = 0, ec = LSS_EC_OK;

	(void)f;
	(void)now_us;
	if (s->constant_id)
		ec = LSS_EC_STORE_UNSUPP;
	else if (s->hooks && s->hooks->store)
		ec = s->hooks->store(s->hook_ctx, s->pending_id, s->bt_valid, s->bt_table,
				     s->bt_index, &spec);
	if (ec == LSS_EC_OK)
		s->persistent_id = s->pending_id;
	answer_code(s, LSS_CS_STORE, ec, spec);
	if (ec == LSS_EC_OK)
		emit(s, CO_EV_LSS_SLAVE_STORE, 0);
}

static void on_inquire(struct lss_slave *s, const co_frame *f, uint64_t now_us)
{
	uint8_t cs = f->data[0];

	(void)now_us;
	if (cs == LSS_CS_INQUIRE_NODE_ID) {
		answer(s, cs, &s->active_id, 1);
		return;
	}
	answer_u32(s, cs, identity(s, (unsigned)(cs - LSS_CS_INQUIRE_VENDOR)));
}

/* ---- identification (waiting and configuration state) --------------------- */

static bool ident_step_matches(const struct lss_slave *s, uint8_t cs, uint32_t v)
{
	switch (cs) {
	case LSS_CS_IDENT_VENDOR:
		return v == identity(s, LSS_ID_VENDOR);
	case LSS_CS_IDENT_PRODUCT:
		return v == identity(s, LSS_ID_PRODUCT);
	case LSS_CS_IDENT_REVISION_LOW:
		return identity(s, LSS_ID_REVISION) >= v;
	case LSS_CS_IDENT_REVISION_HIGH:
		return identity(s, LSS_ID_REVISION) <= v;
	case LSS_CS_IDENT_SERIAL_LOW:
		return identity(s, LSS_ID_SERIAL) >= v;
	case LSS_CS_IDENT_SERIAL_HIGH:
		return identity(s, LSS_ID_SERIAL) <= v;
	default:
		return false;
	}
}

static void on_identify_remote(struct lss_slave *s, const co_frame *f, uint64_t now_us)
{
	uint8_t cs = f->data[0];
	unsigned step = (unsigned)(cs - LSS_CS_IDENT_VENDOR);

	(void)now_us;
	if (step == 0)
		s->ident_matched = 0; /* the vendor frame starts a sequence */
	if (step != s->ident_matched || !ident_step_matches(s, cs, co_get_le32(&f->data[1]))) {
		s->ident_matched = 0xFF; /* wait for the next vendor frame */
		return;
	}
	if (++s->ident_matched < 6)
		return;
	s->ident_matched = 0xFF;
	answer(s, LSS_CS_IDENT_SLAVE, NULL, 0);
}

static void on_identify_non_configured(struct lss_slave *s, const co_frame *f, uint64_t now_us)
{
	(void)f;
	(void)now_us;
	if (unconfigured(s))
		answer(s, LSS_CS_IDENT_NON_CONFIGURED_SLAVE, NULL, 0);
}

/*
 * Fastscan (CiA 305 since 2.2). The master walks the four identity fields
 * (LSSSub), probing one bit at a time from bit 31 down; a slave answers
 * when the bits from BitChecked upward equal its own. BitChecked 80h
 * resets every taking part slave to field 0. A full match of field LSSSub
 * moves the slave on to LSSNext; LSSNext below LSSSub means the master has
 * been through all fields, and the matched slave enters configuration
 * state.
 */
static void on_fastscan(struct lss_slave *s, const co_frame *f, uint64_t now_us)
{
	uint32_t id = co_get_le32(&f->data[1]);
	uint8_t bit = f->data[5], sub = f->data[6], next = f->data[7];
	uint32_t mask;

	(void)now_us;
	if (s->state != LSS_STATE_WAITING || !unconfigured(s))
		return;
	if (bit == LSS_FASTSCAN_CONFIRM) {
		s->fs_pos = 0;
		answer(s, LSS_CS_IDENT_SLAVE, NULL, 0);
		return;
	}
	if (bit > 31 || sub >= LSS_ID_COUNT || next >= LSS_ID_COUNT || sub != s->fs_pos)
		return;
	mask = 0xFFFFFFFFu << bit;
	if ((id ^ identity(s, sub)) & mask)
		return;
	answer(s, LSS_CS_IDENT_SLAVE, NULL, 0);
	if (bit != 0)
		return;
	s->fs_pos = next;
	if (next < sub)
		set_state(s, LSS_STATE_CONFIGURATION);
}

/* ---- dispatch ---------------------------------------------------------------- */

typedef struct lss_slave_cmd {
	uint8_t cs;
	uint8_t config_only; /* processed in configuration state only */
	lss_slave_handler fn;
} lss_slave_cmd;

static const lss_slave_cmd lss_slave_cmds[] = {
	{ LSS_CS_SWITCH_GLOBAL, 0, on_switch_global },
	{ LSS_CS_CONFIG_NODE_ID, 1, on_config_node_id },
	{ LSS_CS_CONFIG_BIT_TIMING, 1, on_config_bit_timing },
	{ LSS_CS_ACTIVATE_BIT_TIMING, 1, on_activate_bit_timing },
	{ LSS_CS_STORE, 1, on_store },
	{ LSS_CS_SWITCH_SEL_VENDOR, 0, on_switch_selective },
	{ LSS_CS_SWITCH_SEL_PRODUCT, 0, on_switch_selective },
	{ LSS_CS_SWITCH_SEL_REVISION, 0, on_switch_selective },
	{ LSS_CS_SWITCH_SEL_SERIAL, 0, on_switch_selective },
	{ LSS_CS_IDENT_VENDOR, 0, on_identify_remote },
	{ LSS_CS_IDENT_PRODUCT, 0, on_identify_remote },
	{ LSS_CS_IDENT_REVISION_LOW, 0, on_identify_remote },
	{ LSS_CS_IDENT_REVISION_HIGH, 0, on_identify_remote },
	{ LSS_CS_IDENT_SERIAL_LOW, 0, on_identify_remote },
	{ LSS_CS_IDENT_SERIAL_HIGH, 0, on_identify_remote },
	{ LSS_CS_IDENT_NON_CONFIGURED, 0, on_identify_non_configured },
	{ LSS_CS_FASTSCAN, 0, on_fastscan },
	{ LSS_CS_INQUIRE_VENDOR, 1, on_inquire },
	{ LSS_CS_INQUIRE_PRODUCT, 1, on_inquire },
	{ LSS_CS_INQUIRE_REVISION, 1, on_inquire },
	{ LSS_CS_INQUIRE_SERIAL, 1, on_inquire },
	{ LSS_CS_INQUIRE_NODE_ID, 1, on_inquire },
};

static void lss_slave_rx(co_node *node, void *arg, const co_frame *f, uint64_t now_us)
{
	struct lss_slave *s = arg;
	co_frame in;

	(void)node;
	/* CiA 305 frames are 8 bytes; a shorter one (some masters trim the
	 * reserved bytes) is read as if padded with zeros. */
	if (f->len < 1 || (f->flags & CO_FRAME_RTR))
		return;
	in = *f;
	for (unsigned i = in.len; i < 8; i++)
		in.data[i] = 0;
	for (size_t i = 0; i < sizeof(lss_slave_cmds) / sizeof(lss_slave_cmds[0]); i++) {
		const lss_slave_cmd *c = &lss_slave_cmds[i];
		if (c->cs != in.data[0])
			continue;
		if (c->config_only && s->state != LSS_STATE_CONFIGURATION)
			return;
		c->fn(s, &in, now_us);
		return;
	}
}

/* ---- lifetime and API ------------------------------------------------------- */

int lss_slave_init(co_node *node, struct lss_slave **out)
{
	struct lss_slave *s = calloc(1, sizeof(*s));
	int rx;

	if (!s)
		return -ENOMEM;
	s->node = node;
	s->state = LSS_STATE_WAITING;
	s->active_id = s->pending_id = s->persistent_id = node->cfg.node_id;
	s->constant_id = node->cfg.lss_slave_constant_id;
	s->hooks = node->cfg.lss_slave_hooks;
	s->hook_ctx = node->cfg.lss_slave_ctx;
	s->ident_matched = 0xFF;
	rx = co_rx_register(node, LSS_COBID_MASTER, 0, lss_slave_rx, s);
	if (rx < 0) {
		free(s);
		return rx;
	}
	s->rx = rx;
	*out = s;
	return 0;
}

void lss_slave_fini(struct lss_slave *s)
{
	if (!s)
		return;
	(void)co_rx_unregister(s->node, s->rx);
	free(s);
}

void lss_slave_reset_comm(struct lss_slave *s, uint64_t now_us)
{
	(void)now_us;
	if (s->active_id == s->pending_id)
		return;
	s->active_id = s->pending_id;
	/* The node's own id: read by every service's reset_comm after this
	 * one (co_svc_lss runs first). */
	s->node->node_id = s->active_id;
	emit(s, CO_EV_LSS_SLAVE_NODE_ID, 0);
}

int lss_slave_get(const co_node *node, lss_state *state, uint8_t *active, uint8_t *pending,
		  uint8_t *persistent)
{
	const struct lss_slave *s = node->lss ? node->lss->slave : NULL;

	if (!s)
		return -ENODEV;
	if (state)
		*state = s->state;
	if (active)
		*active = s->active_id;
	if (pending)
		*pending = s->pending_id;
	if (persistent)
		*persistent = s->persistent_id;
	return 0;
}
