/* SPDX-License-Identifier: MIT */
/*
 * core/pdo_layout.h - what the manager knows of its slaves' PDOs: per node,
 * the valid TPDOs and RPDOs of the *device* (CiA 301 §7.5.2.35/36 records
 * 1400h..1BFFh as the device has them) with the objects they map and, where
 * a file or the configuration names them, the objects' data types.
 *
 * Who fills it (docs/devices.md):
 *   - the configuration, at start-up, from the node's DCF/EDS (source FILE);
 *   - the manager's PDO layout step of the boot slave process, by reading the
 *     records over SDO (source SCAN; SDO cannot reveal a data type, so a
 *     scanned entry has type 0 unless the file or configuration gives one).
 * Who reads it: the device object layer of the line (mirror PDOs, typed
 * values, writes by PDO), `cogwctl pdo map`.
 *
 * Direction is the device's: CO_PDO_TX = a TPDO of the device (values come
 * from it), CO_PDO_RX = an RPDO of the device (values go to it).
 *
 * A table belongs to one line and is used on its thread only. Everything is
 * allocated by co_pdo_layout_create(); nothing later.
 */
#ifndef COGW_CORE_PDO_LAYOUT_H
#define COGW_CORE_PDO_LAYOUT_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "core/pdo.h"

#define CO_PDO_LAYOUT_NODES 127u
#define CO_PDO_LAYOUT_CAP_DEFAULT 8u /* PDOs per direction and node */

typedef struct co_pdo_layout_entry {
	uint16_t index; /* 0001h..0007h: a dummy entry (RPDO of the device) */
	uint8_t sub;
	uint8_t bits;   /* mapped length, 1..64 */
	uint8_t offset; /* first bit in the frame (LSB first, CiA 301 §7.4.7.1) */
	uint8_t access; /* CO_ACC_* the file gives, 0 = unknown */
	uint16_t type;  /* co_type the file/configuration gives, 0 = unknown:
	                 * the value is an unsigned integer of `bits` bits */
} co_pdo_layout_entry;

typedef struct co_pdo_layout_pdo {
	uint16_t nr;  /* PDO number on the device, 1..512 */
	uint32_t cob; /* communication sub 1 (bit 31 clear: only valid ones are kept) */
	uint8_t tt;   /* transmission type */
	uint8_t sync_start;
	uint16_t inhibit;  /* 100 µs (TPDO) */
	uint16_t event_ms; /* TPDO: event timer; RPDO: the device's deadline */
	uint8_t n;         /* entries in map[] */
	uint8_t bytes;     /* frame length the mapping gives */
	co_pdo_layout_entry map[CO_PDO_MAX_MAP];
} co_pdo_layout_pdo;

typedef enum co_pdo_layout_source {
	CO_PDO_LAYOUT_NONE = 0,
	CO_PDO_LAYOUT_FILE = 1, /* DCF/EDS the node is configured with */
	CO_PDO_LAYOUT_SCAN = 2, /* read from the device over SDO */
} co_pdo_layout_source;

typedef struct co_pdo_layout_node {
	uint8_t source;      /* co_pdo_layout_source of the current content */
	bool valid;          /* learned and not invalidated since */
	uint32_t generation; /* +1 at every change: learnt, invalidated */
	uint64_t learned_us; /* when it was learnt */
	uint16_t cap;        /* room per direction */
	uint16_t n[2];       /* valid PDOs kept, per direction (co_pdo_dir) */
	uint16_t dropped[2]; /* valid PDOs beyond cap: not kept, reported */
	co_pdo_layout_pdo *pdo[2];
} co_pdo_layout_node;

typedef struct co_pdo_layout co_pdo_layout;

/* What is known of one object of a node besides the PDO records: its data
 * type and access, from the node's EDS/DCF or the configuration's "types"
 * (docs/config.md "PDO layouts"). A list is sorted by index, then sub, and
 * read-only once built (start-up). */
typedef struct co_pdo_layout_type {
	uint16_t index;
	uint8_t sub;
	uint8_t access; /* CO_ACC_* (core/od.h), 0 = unknown */
	uint16_t type;  /* co_type */
} co_pdo_layout_type;

/* Room for `cap` PDOs per direction for every node set in `nodes` (bit n of
 * word n / 32 = node n, as co_mgr_bits). -EINVAL, -ENOMEM. */
int co_pdo_layout_create(co_pdo_layout **out, const uint32_t nodes[4], uint16_t cap);
void co_pdo_layout_destroy(co_pdo_layout *t); /* accepts NULL */

/* The node's record, NULL when the table has no room for it. */
co_pdo_layout_node *co_pdo_layout_node_of(co_pdo_layout *t, uint8_t node);
const co_pdo_layout_node *co_pdo_layout_node_get(const co_pdo_layout *t, uint8_t node);

/* Start a new content for `node` (clears both directions, valid = false,
 * generation + 1). -ENOENT: no room for the node. */
int co_pdo_layout_begin(co_pdo_layout *t, uint8_t node, co_pdo_layout_source src);
/* Keep one valid PDO (entries' offsets and `bytes` are computed here).
 * Returns the kept record, or NULL when the node's room is full (counted in
 * dropped[dir]). */
co_pdo_layout_pdo *co_pdo_layout_add(co_pdo_layout *t, uint8_t node, co_pdo_dir dir,
				     const co_pdo_layout_pdo *pdo);
/* The content is complete: valid = true, generation + 1. */
void co_pdo_layout_commit(co_pdo_layout *t, uint8_t node, uint64_t now_us);
/* The device may have changed (boot-up, new configuration): valid = false,
 * generation + 1; the content stays for display until learnt again. */
void co_pdo_layout_invalidate(co_pdo_layout *t, uint8_t node);

/* Where object index:sub of `node` is mapped in direction `dir`: the first
 * valid PDO that maps it (*pdo, *pos = entry number). false: not mapped. */
bool co_pdo_layout_find(const co_pdo_layout *t, uint8_t node, co_pdo_dir dir, uint16_t index,
			uint8_t sub, const co_pdo_layout_pdo **pdo, uint8_t *pos);

/* The entry of index:sub in a sorted list of n, NULL when it has none. */
const co_pdo_layout_type *co_pdo_layout_type_find(const co_pdo_layout_type *list, size_t n,
						  uint16_t index, uint8_t sub);

/* One PDO as a line of text, for logs and the CLI:
 * "TPDO 1 COB-ID 185h tt 254 inhibit 0 event 100 ms: 6000:01/8 UNSIGNED8,
 * 0002:00/8 (dummy)". Returns what snprintf returns. */
int co_pdo_layout_pdo_format(char *buf, size_t len, co_pdo_dir dir, const co_pdo_layout_pdo *p);

/* "none", "file", "scan". */
const char *co_pdo_layout_source_to_string(uint8_t src);

#endif /* COGW_CORE_PDO_LAYOUT_H */
