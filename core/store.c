/* SPDX-License-Identifier: MIT */
/*
 * Store/restore parameters (1010h/1011h). The signatures exist so that a
 * stray write (a wrong index, a tool probing objects) cannot wipe or
 * freeze the configuration by accident: only the exact 32-bit value
 * "save"/"load" acts (CiA 301 §7.5.2.13/14).
 */
#include <errno.h>
#include <stdlib.h>

#include "core/co_internal.h"
#include "core/sdo.h"
#include "core/store.h"

struct co_store {
	co_node *node;
	const co_store_ops *ops;
	void *ctx;
	uint8_t n_subs;
	uint32_t caps[2]; /* [0] = 1010h, [1] = 1011h */
};

static bool is_save(const co_od_entry *e)
{
	return e->index == CO_STORE_IDX_SAVE;
}

static uint32_t store_check(void *ctx, co_od_entry *e, const co_od_access *a)
{
	struct co_store *st = ctx;
	bool save = is_save(e);
	uint32_t ab = 0;

	if (!a->data || a->size != 4)
		return SDO_AB_TYPE_LEN;
	if (co_get_le32(a->data) != (save ? CO_STORE_SIG_SAVE : CO_STORE_SIG_LOAD))
		return SDO_AB_STORE;
	if (st->ops) {
		uint32_t (*fn)(void *, uint8_t, const co_od_access *) = save ? st->ops->save
									     : st->ops->restore;
		if (fn)
			ab = fn(st->ctx, e->sub, a);
	}
	if (ab == 0 || ab == CO_OD_DEFERRED) {
		co_event ev = { .kind = save ? CO_EV_STORE : CO_EV_RESTORE };
		ev.u.store.index = e->index;
		ev.u.store.sub = e->sub;
		co_node_emit(st->node, &ev);
	}
	return ab;
}

/* The signature is a command, not a value: reads keep returning the
 * capability bits. */
static void store_written(void *ctx, co_od_entry *e, const co_od_access *a)
{
	struct co_store *st = ctx;

	(void)a;
	co_od_entry_set_raw(e, st->caps[is_save(e) ? 0 : 1]);
}

static const co_od_hooks store_hooks = {
	.check_write = store_check,
	.after_write = store_written,
};

static int attach_index(struct co_store *st, uint16_t idx, uint32_t caps)
{
	co_od *od = st->node->od;
	co_od_entry *e;
	int rc;

	if (!co_od_has_index(od, idx)) {
		rc = co_od_add_array(od, idx, CO_T_UNSIGNED32, st->n_subs, CO_ACC_RW, caps);
		if (rc)
			return rc;
	}
	for (unsigned s = 1; s <= 0x7F; s++) {
		e = co_od_find(od, idx, (uint8_t)s);
		if (!e || e->type != CO_T_UNSIGNED32)
			continue;
		co_od_entry_set_default_raw(e, caps);
		co_od_entry_set_raw(e, caps);
		co_od_entry_set_hooks(e, &store_hooks, st);
	}
	return 0;
}

static void detach(co_node *node, struct co_store *st)
{
	for (uint16_t idx = CO_STORE_IDX_SAVE; idx <= CO_STORE_IDX_LOAD; idx++) {
		for (unsigned s = 1; s <= 0x7F; s++) {
			co_od_entry *e = co_od_find(node->od, idx, (uint8_t)s);
			if (e && e->hook_ctx == st)
				co_od_entry_set_hooks(e, NULL, NULL);
		}
	}
}

int co_store_attach(co_node *node, const co_store_ops *ops, void *ctx, uint8_t n_subs,
		    uint32_t save_caps, uint32_t restore_caps)
{
	struct co_store *st;
	int rc;

	if (!node || n_subs < 1 || n_subs > 127)
		return -EINVAL;
	if (node->store)
		return -EEXIST;
	st = calloc(1, sizeof(*st));
	if (!st)
		return -ENOMEM;
	st->node = node;
	st->ops = ops;
	st->ctx = ctx;
	st->n_subs = n_subs;
	st->caps[0] = save_caps;
	st->caps[1] = restore_caps;
	rc = attach_index(st, CO_STORE_IDX_SAVE, save_caps);
	if (!rc)
		rc = attach_index(st, CO_STORE_IDX_LOAD, restore_caps);
	if (rc) {
		detach(node, st);
		free(st);
		return rc;
	}
	node->store = st;
	return 0;
}

static void store_fini(co_node *node)
{
	if (!node->store)
		return;
	detach(node, node->store);
	free(node->store);
	node->store = NULL;
}

const co_service co_svc_store = {
	.name = "store",
	.fini = store_fini,
};
