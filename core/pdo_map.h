/* SPDX-License-Identifier: MIT */
/*
 * core/pdo_map.h - internals shared by core/pdo.c (runtime) and
 * core/pdo_map.c (mapping validation/compilation, allocation, OD builder).
 * Not an API: applications use core/pdo.h.
 */
#ifndef COGW_CORE_PDO_MAP_H
#define COGW_CORE_PDO_MAP_H

#include <stdbool.h>
#include <stdint.h>

#include "core/co.h"
#include "core/pdo.h"

/* One compiled mapping entry: where the bits go, and the object. */
typedef struct pdo_item {
	co_od_entry *e; /* NULL = dummy entry */
	uint8_t off;    /* bit offset in the PDO, LSB first */
	uint8_t bits;
} pdo_item;

struct pdo {
	uint16_t nr; /* 1-based */
	uint8_t dir; /* co_pdo_dir */
	uint8_t tt;
	uint32_t cob; /* comm sub 1 in force */
	uint16_t inhibit_100us;
	uint16_t event_ms;
	uint8_t sync_start;
	uint8_t cap;            /* mapping subs 1..cap exist in the OD */
	uint8_t n;              /* compiled entries in force */
	uint8_t len;            /* PDO length in bytes */
	bool map_ok;            /* mapping compiled (n may be 0) */
	bool valid;             /* COB-ID valid and map_ok */
	int rx_h;               /* receiver (RPDO data / TPDO RTR) */
	co_od_entry *e_comm[7]; /* comm subs 0..6, NULL if absent */
	co_od_entry *e_map0;    /* mapping sub 0 */
	co_od_entry **e_map;    /* mapping subs 1..cap */
	pdo_item *items;        /* cap slots, n in force */
	co_ev_pdo_map *evmap;   /* same, as reported in events */

	/* runtime, reset by pdo_runtime_reset() */
	uint8_t buf[8]; /* RPDO: data waiting for SYNC; TPDO 252: sample */
	uint8_t buf_len;
	bool pending;       /* RPDO: buf waits; TPDO TT 0: event since SYNC */
	bool sampled;       /* TPDO TT 252: buf is valid */
	bool event_pending; /* TPDO 254/255: event waits for the inhibit time */
	bool wait_start;    /* TPDO 1..240: waiting for the SYNC start value */
	uint8_t faults;     /* RPDO supervision episodes under way (CO_PDO_FAULT_*) */
	uint8_t sync_cnt;
	uint64_t inhibit_until;
	uint64_t timer_us; /* event timer / RPDO deadline, CO_NO_DEADLINE off */
	uint64_t due;      /* heap key */
	uint16_t hpos;     /* heap position, 0xFFFF = not in the heap */
};

/* (object -> TPDO) index entry */
struct pdo_rev {
	uint32_t key; /* index << 8 | sub */
	uint16_t pdo; /* position in v */
};

struct co_pdo {
	co_node *node;
	struct pdo *v; /* RPDOs [0, n_rx), TPDOs [n_rx, n_rx + n_tx) */
	uint16_t n_rx, n_tx;
	uint16_t slot[2][CO_PDO_MAX]; /* [dir][nr - 1] -> position, 0xFFFF */
	co_od_entry **entry_pool;
	pdo_item *item_pool;
	co_ev_pdo_map *evmap_pool;
	uint16_t *heap;
	uint16_t heap_n;
	uint16_t *sync_list;
	uint16_t sync_n;
	bool sync_dirty;
	struct pdo_rev *rev;
	uint32_t rev_n;
	bool rev_dirty;
	bool operational;
	uint16_t fault_count[CO_PDO_FAULT_KINDS]; /* RPDOs with each fault's EMCY */
	co_pdo_tx_gate_fn gate;                   /* co_pdo_set_tx_gate(), NULL = none */
	void *gate_ctx;
	co_pdo_stats stats;
};

/* Which PDO an object of 1400h..1BFFh belongs to (NULL if none). */
struct pdo *pdo_of_index(struct co_pdo *P, uint16_t index, bool *is_map);

/* Count the PDOs in the OD, allocate every array. 0 or -ENOMEM. */
int pdo_map_alloc(struct co_pdo *P);
void pdo_map_free(struct co_pdo *P);

/* Compile the mapping in the OD into p. False (and nothing mapped,
 * map_ok false) if the OD holds an invalid mapping. */
bool pdo_map_compile(struct co_pdo *P, struct pdo *p);
/* Checks for an SDO/local write of mapping sub 0 = n / of an entry. */
uint32_t pdo_map_check_count(struct co_pdo *P, const struct pdo *p, uint8_t n);
uint32_t pdo_map_check_entry(struct co_pdo *P, const struct pdo *p, uint32_t v);

/* TPDO: sample the mapped objects into out (8 bytes, zero padded). */
void pdo_map_pack(const struct pdo *p, uint8_t out[8]);
/* RPDO: write entry i from data into the OD; 0 or the OD's abort code. */
uint32_t pdo_map_unpack_one(const struct pdo *p, uint8_t i, const uint8_t *data, uint8_t len);

void pdo_map_rev_rebuild(struct co_pdo *P);

#endif /* COGW_CORE_PDO_MAP_H */
