/* SPDX-License-Identifier: MIT */
/*
 * The learned PDO layouts of a line's slaves (core/pdo_layout.h). One block
 * holds every record so that learning at run time never allocates.
 */
#include "core/pdo_layout.h"

#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "core/od.h"

struct co_pdo_layout {
	co_pdo_layout_node *node[CO_PDO_LAYOUT_NODES]; /* [id - 1], NULL = no room */
	co_pdo_layout_node *nodes;                     /* the block of node records */
	co_pdo_layout_pdo *pdos;                       /* the block of PDO records */
};

static bool bit_set(const uint32_t w[4], unsigned id)
{
	return (w[id / 32u] >> (id % 32u)) & 1u;
}

int co_pdo_layout_create(co_pdo_layout **out, const uint32_t nodes[4], uint16_t cap)
{
	*out = NULL;
	if (cap == 0 || cap > CO_PDO_MAX)
		return -EINVAL;
	unsigned count = 0;
	for (unsigned id = 1; id <= CO_PDO_LAYOUT_NODES; id++)
		count += bit_set(nodes, id);
	co_pdo_layout *t = calloc(1, sizeof *t);
	if (!t)
		return -ENOMEM;
	if (count) {
		t->nodes = calloc(count, sizeof *t->nodes);
		t->pdos = calloc((size_t)count * 2u * cap, sizeof *t->pdos);
		if (!t->nodes || !t->pdos) {
			co_pdo_layout_destroy(t);
			return -ENOMEM;
		}
	}
	unsigned k = 0;
	for (unsigned id = 1; id <= CO_PDO_LAYOUT_NODES; id++) {
		if (!bit_set(nodes, id))
			continue;
		co_pdo_layout_node *n = &t->nodes[k];
		n->cap = cap;
		n->pdo[CO_PDO_RX] = &t->pdos[(size_t)k * 2u * cap];
		n->pdo[CO_PDO_TX] = n->pdo[CO_PDO_RX] + cap;
		t->node[id - 1] = n;
		k++;
	}
	*out = t;
	return 0;
}

void co_pdo_layout_destroy(co_pdo_layout *t)
{
	if (!t)
		return;
	free(t->pdos);
	free(t->nodes);
	free(t);
}

co_pdo_layout_node *co_pdo_layout_node_of(co_pdo_layout *t, uint8_t node)
{
	if (!t || node < 1 || node > CO_PDO_LAYOUT_NODES)
		return NULL;
	return t->node[node - 1];
}

const co_pdo_layout_node *co_pdo_layout_node_get(const co_pdo_layout *t, uint8_t node)
{
	return co_pdo_layout_node_of((co_pdo_layout *)t, node);
}

int co_pdo_layout_begin(co_pdo_layout *t, uint8_t node, co_pdo_layout_source src)
{
	co_pdo_layout_node *n = co_pdo_layout_node_of(t, node);
	if (!n)
		return -ENOENT;
	n->source = (uint8_t)src;
	n->valid = false;
	n->generation++;
	n->learned_us = 0;
	for (unsigned d = 0; d < 2; d++) {
		n->n[d] = 0;
		n->dropped[d] = 0;
	}
	return 0;
}

co_pdo_layout_pdo *co_pdo_layout_add(co_pdo_layout *t, uint8_t node, co_pdo_dir dir,
				     const co_pdo_layout_pdo *pdo)
{
	co_pdo_layout_node *n = co_pdo_layout_node_of(t, node);
	if (!n || (dir != CO_PDO_RX && dir != CO_PDO_TX) || pdo->n > CO_PDO_MAX_MAP)
		return NULL;
	if (n->n[dir] >= n->cap) {
		n->dropped[dir]++;
		return NULL;
	}
	co_pdo_layout_pdo *p = &n->pdo[dir][n->n[dir]++];
	*p = *pdo;
	unsigned bit = 0;
	for (unsigned i = 0; i < p->n; i++) {
		p->map[i].offset = (uint8_t)(bit < 255u ? bit : 255u);
		bit += p->map[i].bits;
	}
	p->bytes = (uint8_t)((bit + 7u) / 8u > 255u ? 255u : (bit + 7u) / 8u);
	return p;
}

void co_pdo_layout_commit(co_pdo_layout *t, uint8_t node, uint64_t now_us)
{
	co_pdo_layout_node *n = co_pdo_layout_node_of(t, node);
	if (!n)
		return;
	n->valid = true;
	n->generation++;
	n->learned_us = now_us;
}

void co_pdo_layout_invalidate(co_pdo_layout *t, uint8_t node)
{
	co_pdo_layout_node *n = co_pdo_layout_node_of(t, node);
	if (!n || !n->valid)
		return;
	n->valid = false;
	n->generation++;
}

bool co_pdo_layout_find(const co_pdo_layout *t, uint8_t node, co_pdo_dir dir, uint16_t index,
			uint8_t sub, const co_pdo_layout_pdo **pdo, uint8_t *pos)
{
	const co_pdo_layout_node *n = co_pdo_layout_node_get(t, node);
	if (!n || !n->valid || (dir != CO_PDO_RX && dir != CO_PDO_TX))
		return false;
	for (unsigned k = 0; k < n->n[dir]; k++) {
		const co_pdo_layout_pdo *p = &n->pdo[dir][k];
		for (unsigned i = 0; i < p->n; i++) {
			if (p->map[i].index == index && p->map[i].sub == sub) {
				*pdo = p;
				*pos = (uint8_t)i;
				return true;
			}
		}
	}
	return false;
}

const co_pdo_layout_type *co_pdo_layout_type_find(const co_pdo_layout_type *list, size_t n,
						  uint16_t index, uint8_t sub)
{
	uint32_t key = (uint32_t)index << 8 | sub;
	size_t lo = 0, hi = n;

	while (lo < hi) {
		size_t mid = lo + (hi - lo) / 2;
		uint32_t at = (uint32_t)list[mid].index << 8 | list[mid].sub;
		if (at == key)
			return &list[mid];
		if (at < key)
			lo = mid + 1;
		else
			hi = mid;
	}
	return NULL;
}

int co_pdo_layout_pdo_format(char *buf, size_t len, co_pdo_dir dir, const co_pdo_layout_pdo *p)
{
	size_t off = 0;
	int n = snprintf(buf, len, "%s %u COB-ID %Xh tt %u inhibit %u event %u ms:",
			 dir == CO_PDO_TX ? "TPDO" : "RPDO", p->nr, (unsigned)p->cob, p->tt,
			 p->inhibit, p->event_ms);
	if (n < 0)
		return n;
	off = (size_t)n;
	if (p->n == 0 && off < len)
		off += (size_t)snprintf(buf + off, len - off, " (no mapping)");
	for (unsigned i = 0; i < p->n && off < len; i++) {
		const co_pdo_layout_entry *e = &p->map[i];
		bool dummy = e->index >= 1 && e->index <= 7;
		off += (size_t)snprintf(buf + off, len - off, "%s %04X:%02X/%u %s", i ? "," : "",
					e->index, e->sub, e->bits,
					dummy     ? "(dummy)"
					: e->type ? co_type_to_string((co_type)e->type)
						  : "(type unknown)");
	}
	return (int)off;
}

const char *co_pdo_layout_source_to_string(uint8_t src)
{
	switch (src) {
	case CO_PDO_LAYOUT_FILE:
		return "file";
	case CO_PDO_LAYOUT_SCAN:
		return "scan";
	default:
		return "none";
	}
}
