/* SPDX-License-Identifier: MIT */
/*
 * devobj/object.c - where a device object is (the device PDO that maps it
 * and the daemon record mirroring that PDO) and the answer of a command:
 * what the command files of the extension share (devobj/devobj_int.h).
 */
#include "devobj/devobj_int.h"

bool devobj_find(const devobj_line *dl, uint8_t node, co_pdo_dir dev_dir, uint16_t index,
		 uint8_t sub, devobj_place *out)
{
	const co_pdo_layout_node *n = co_pdo_layout_node_get(line_pdo_layout(dl->l), node);
	bool found = false;
	if (!n || !n->valid)
		return false;
	/* an object mapped in several PDOs: the first that is mirrored */
	for (uint16_t k = 0; k < n->n[dev_dir]; k++) {
		const co_pdo_layout_pdo *p = &n->pdo[dev_dir][k];
		for (uint8_t i = 0; i < p->n; i++) {
			if (p->map[i].index != index || p->map[i].sub != sub)
				continue;
			int rec = devobj_mirror_record_for(&dl->mirror, node, dev_dir, k);
			if (!found || rec >= 0)
				*out = (devobj_place){
					.pdo = p, .entry = &p->map[i], .pos = i, .rec = rec
				};
			found = true;
			if (rec >= 0)
				return true;
		}
	}
	return found;
}

void devobj_answer(devobj_line *dl, const mbx_reply_to *to, int status, uint32_t abort,
		   const void *payload, size_t len)
{
	mbx_server_respond(line_mbx(dl->l), to, status, abort, payload, len);
}
