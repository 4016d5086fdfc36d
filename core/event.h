/* SPDX-License-Identifier: MIT */
/*
 * core/event.h - what the core tells the application (through the event
 * callback given to co_node_create()).
 *
 * An event is a tagged struct, valid only during the callback: copy what you
 * need. Pointers inside (e.g. SDO upload data) point to caller-owned or
 * core-owned memory that stays valid until the callback returns.
 *
 * Adding a kind: append to enum co_event_kind (never renumber), add a
 * member to the union, and a name in co_event_kind_to_string() (event.c).
 */
#ifndef COGW_CORE_EVENT_H
#define COGW_CORE_EVENT_H

#include <stdint.h>

#include "core/frame.h"

typedef enum co_event_kind {
	CO_EV_NONE = 0,
	CO_EV_OD_WRITTEN,      /* an object was written over SDO: u.od */
	CO_EV_SDO_SERVER_DONE, /* a server transfer ended: u.sdo_srv */
	CO_EV_SDO_CLIENT_DONE, /* a client request completed: u.sdo_cli */
	CO_EV_STORE,           /* 1010h "save" accepted: u.store */
	CO_EV_RESTORE,         /* 1011h "load" accepted: u.store */
	CO_EV_RX_UNHANDLED,    /* frame with no receiver: u.frame */
	CO_EV_TX_FAILED,       /* send callback failed: u.frame */
	/* NMT and error control (core/nmt.c, heartbeat.c, guarding.c) */
	CO_EV_NMT_STATE,          /* own NMT state changed: u.nmt */
	CO_EV_BOOTUP,             /* boot-up from any node: u.errctrl */
	CO_EV_HB_STARTED,         /* monitored heartbeat (re)started: u.errctrl */
	CO_EV_HB_LOST,            /* heartbeat consumer timeout: u.errctrl */
	CO_EV_HB_STATE,           /* remote node changed state: u.errctrl */
	CO_EV_GUARD_LIFE_LOST,    /* slave: no guard RTR within life time */
	CO_EV_GUARD_LIFE_RESUMED, /* slave: guard RTR again after a loss */
	CO_EV_GUARD_FAILED,       /* master: guarded node silent: u.errctrl */
	CO_EV_GUARD_TOGGLE,       /* master: toggle bit repeated: u.errctrl */
	CO_EV_GUARD_RESUMED,      /* master: guarded node answers again */
	/* EMCY (core/emcy.c) */
	CO_EV_EMCY_RX, /* EMCY consumed (1028h): u.emcy */
	/* SYNC, TIME, PDO (core/sync.c, time.c, pdo.c) */
	CO_EV_SYNC,         /* SYNC received or produced: u.sync */
	CO_EV_TIME,         /* TIME stamp consumed: u.time */
	CO_EV_RPDO,         /* RPDO committed to the OD: u.pdo */
	CO_EV_RPDO_OBJECT,  /* one object written by an RPDO: u.pdo_obj */
	CO_EV_RPDO_TIMEOUT, /* RPDO deadline (event timer) ran out: u.pdo */
	CO_EV_RPDO_LENGTH,  /* RPDO of the wrong length: u.pdo */
	/* LSS (core/lss_master.c, core/lss_slave.c) */
	CO_EV_LSS_MASTER_DONE,      /* an LSS master request ended: u.lss_master */
	CO_EV_LSS_SLAVE_STATE,      /* slave: waiting <-> configuration: u.lss_slave */
	CO_EV_LSS_SLAVE_NODE_ID,    /* slave: pending or active node-ID changed */
	CO_EV_LSS_SLAVE_STORE,      /* slave: store configuration accepted */
	CO_EV_LSS_SLAVE_BIT_TIMING, /* slave: activate bit timing (switch the
	                             * controller after delay_ms) */
	/* CiA 302-2 manager (core/manager.c): u.mgr */
	CO_EV_MGR_STATE, /* line state or flags changed */
	CO_EV_MGR_BOOT,  /* one step of a node's boot slave process */
	CO_EV_MGR_NODE,  /* unexpected/late/lost/duplicate node, ... */
	/* SDO client (core/sdo_client.c): a second answer to a request the
	 * server already answered (two devices on one node-ID): u.sdo_cli
	 * (node_id, index, sub; abort = that answer's abort code or 0) */
	CO_EV_SDO_CLIENT_SECOND_ANSWER,
	/* PDO (core/pdo.c): a correct RPDO (or a reconfiguration) ended the
	 * supervision episodes u.pdo.fault of that RPDO */
	CO_EV_RPDO_RECOVERED,
	/* An object of the node was given a value from outside its own
	 * services - the gateway's process image, updated by another line
	 * (docs/gateway.md): u.pdo_obj (nr 0, bits = the object's size x 8).
	 * Emitted by the extension that stored it, for the others. */
	CO_EV_OBJECT_UPDATED,
	/* A communication fault of the node began or ended (core/commfault.c):
	 * u.commfault */
	CO_EV_COMM_FAULT,
	/* other services append here: NMT, HB, EMCY, SYNC, TIME, PDO, LSS */
	CO_EV_KIND_COUNT
} co_event_kind;

const char *co_event_kind_to_string(co_event_kind k);

typedef struct co_ev_od {
	uint16_t index;
	uint8_t sub;
	uint8_t channel; /* SDO server channel */
	uint32_t size;
} co_ev_od;

typedef struct co_ev_sdo_srv {
	uint8_t channel;
	uint8_t upload; /* 1 = read by the client, 0 = written */
	uint16_t index;
	uint8_t sub;
	uint8_t mode;   /* sdo_mode actually used */
	uint32_t abort; /* 0 = success */
	uint32_t size;  /* bytes transferred */
} co_ev_sdo_srv;

typedef struct co_ev_sdo_cli {
	uint8_t channel;
	uint8_t upload;  /* 1 = upload (read), 0 = download (write) */
	uint8_t node_id; /* target */
	uint8_t mode;    /* sdo_mode actually used (after any fallback) */
	uint16_t index;
	uint8_t sub;
	uint32_t abort;      /* 0 = success, else CiA abort code (local or remote) */
	uint32_t size;       /* bytes transferred */
	uint64_t tag;        /* caller's correlation id, echoed */
	const uint8_t *data; /* upload into a buffer: that buffer, else NULL */
	bool answered;       /* the server answered the transfer at least once */
} co_ev_sdo_cli;

typedef struct co_ev_store {
	uint16_t index; /* 1010h or 1011h */
	uint8_t sub;    /* 1 all, 2 comm, 3 application, 4.. manufacturer */
} co_ev_store;

/* CO_EV_NMT_STATE */
typedef struct co_ev_nmt {
	uint8_t state; /* enum co_nmt_state (core/nmt.h) */
	uint8_t prev;
	uint8_t cs; /* command that caused it; 0 = boot, error behaviour
	                * (1029h) or reset completion */
} co_ev_nmt;

/* CO_EV_BOOTUP, CO_EV_HB_*, CO_EV_GUARD_* */
typedef struct co_ev_errctrl {
	uint8_t node;     /* remote node-id (own id for GUARD_LIFE_*) */
	uint8_t state;    /* state last seen (enum co_nmt_state), 0xFF unknown */
	uint8_t prev;     /* HB_STATE: previous state, 0xFF unknown */
	uint8_t guarded;  /* 1: seen through node guarding, 0: heartbeat */
	uint16_t time_ms; /* consumer time / guard time in force */
} co_ev_errctrl;

/* CO_EV_COMM_FAULT */
typedef struct co_ev_commfault {
	uint8_t fault;        /* enum co_comm_fault (core/commfault.h) */
	uint8_t active;       /* 1 = the episode began, 0 = it ended */
	uint8_t info;         /* ID collision: the state byte heard */
	uint32_t episodes;    /* of this fault since the counters' reset */
	uint32_t occurrences; /* likewise */
	uint64_t since_us;    /* begin of the episode */
} co_ev_commfault;

/* CO_EV_EMCY_RX */
typedef struct co_ev_emcy {
	uint8_t node;    /* 1028h sub-index = producer node-id */
	uint8_t reg;     /* producer's error register (1001h) */
	uint16_t code;   /* emergency error code */
	uint8_t msef[5]; /* manufacturer-specific error field */
	uint32_t cob_id;
} co_ev_emcy;

/* CO_EV_SYNC */
typedef struct co_ev_sync {
	uint8_t counter;  /* SYNC counter (1..1019h), 0 = frame has none */
	uint8_t produced; /* 1 = this node sent it, 0 = received */
} co_ev_sync;

/* CO_EV_TIME: TIME_OF_DAY (core/time.h) */
typedef struct co_ev_time {
	uint32_t ms;      /* milliseconds after midnight */
	uint16_t days;    /* days since 1984-01-01 */
	uint8_t produced; /* 1 = this node sent it, 0 = consumed */
} co_ev_time;

/* One mapped object of a PDO (dummy entries have index 0001h..0007h). */
typedef struct co_ev_pdo_map {
	uint16_t index;
	uint8_t sub;
	uint8_t bits;
} co_ev_pdo_map;

/* RPDO supervision faults (CiA 301 §7.5.2.35 deadline, §7.5.2.36 length),
 * one bit each so that one CO_EV_RPDO_RECOVERED can end several. */
enum co_pdo_fault {
	CO_PDO_FAULT_TIMEOUT = 1u << 0, /* deadline missed: EMCY 8250h */
	CO_PDO_FAULT_SHORT = 1u << 1,   /* shorter than mapped, not processed: 8210h */
	CO_PDO_FAULT_LONG = 1u << 2,    /* longer than mapped, leading bytes used: 8220h */
};
#define CO_PDO_FAULT_KINDS 3u

/* CO_EV_RPDO, CO_EV_RPDO_TIMEOUT, CO_EV_RPDO_LENGTH, CO_EV_RPDO_RECOVERED */
typedef struct co_ev_pdo {
	uint16_t nr;        /* 1-based PDO number (RPDO n = 1400h + n - 1) */
	uint8_t len;        /* bytes in data (RPDO: received length; 0 for
	                      * TIMEOUT, and RECOVERED by a reconfiguration) */
	uint8_t mapped_len; /* bytes the mapping in force needs */
	uint8_t fault;      /* TIMEOUT/LENGTH: the CO_PDO_FAULT_* that began;
	                      * RECOVERED: those that ended; else 0 */
	uint16_t event_ms;  /* RPDO deadline in force (1400h+n-1:5), 0 = none */
	uint8_t n_map;      /* entries in map */
	uint32_t cob_id;    /* CAN-ID (with CO_FRAME_EXT in flags) */
	uint8_t flags;
	uint8_t data[8];
	const co_ev_pdo_map *map; /* the mapping in force, n_map entries */
} co_ev_pdo;

/* CO_EV_RPDO_OBJECT */
typedef struct co_ev_pdo_obj {
	uint16_t nr; /* 1-based RPDO number */
	uint16_t index;
	uint8_t sub;
	uint8_t bits;   /* mapped length */
	uint32_t abort; /* 0 = written, else why the OD refused the value */
} co_ev_pdo_obj;

/* CO_EV_LSS_MASTER_DONE (core/lss_master.h) */
typedef struct co_ev_lss_master {
	uint8_t service;      /* enum lss_master_service */
	uint8_t result;       /* enum lss_result */
	uint8_t error_code;   /* LSS_RESULT_SLAVE_ERROR: the slave's code */
	uint8_t error_spec;   /* implementation specific byte (code 0xFF) */
	uint8_t node_id;      /* INQUIRE_NODE_ID: answer; CONFIG_NODE_ID: sent */
	uint16_t answers;     /* answer frames seen (identify, Fastscan) */
	uint32_t value;       /* INQUIRE_VENDOR..SERIAL: answer */
	uint32_t identity[4]; /* FASTSCAN: vendor, product, revision, serial */
	uint64_t tag;         /* caller's correlation id, echoed */
} co_ev_lss_master;

/* CO_EV_LSS_SLAVE_* (core/lss_slave.h) */
typedef struct co_ev_lss_slave {
	uint8_t state;     /* enum lss_state after the change */
	uint8_t active_id; /* node-IDs after the change (255 = none) */
	uint8_t pending_id;
	uint8_t persistent_id;
	uint8_t bt_table; /* STORE/BIT_TIMING: configured bit timing */
	uint8_t bt_index;
	uint8_t bt_valid;  /* 1 if a bit timing was configured */
	uint16_t delay_ms; /* BIT_TIMING: switch delay */
} co_ev_lss_slave;

/* CO_EV_MGR_* (core/manager.h) */
typedef struct co_ev_mgr {
	uint8_t node;      /* 0 = the line (MGR_STATE) */
	uint8_t state;     /* MGR_STATE: co_mgr_state */
	uint8_t prev;      /* MGR_STATE: previous co_mgr_state */
	uint8_t flags;     /* MGR_STATE/BOOT: CO_MGR_F_* of the line */
	uint8_t step;      /* MGR_BOOT: co_mgr_step */
	char status;       /* MGR_BOOT: CiA 302-2 letter, 0 = step passed */
	uint8_t what;      /* MGR_NODE: co_mgr_node_what */
	uint8_t mandatory; /* MGR_BOOT/NODE: 1 = mandatory slave */
	uint16_t index;    /* MGR_BOOT: object of the step (0 = none) */
	uint8_t sub;
	uint8_t done;      /* MGR_BOOT: 1 = last step (booted or failed) */
	uint32_t abort;    /* MGR_BOOT: SDO abort code, 0 = none */
	uint32_t value;    /* BOOT: the value read; configure step: the
	                    * concise DCF entry refused (status J, 1-based)
	                    * or the entries written; NODE: detail */
	uint32_t expected; /* MGR_BOOT: value expected (1F84h..1F88h) */
} co_ev_mgr;

typedef struct co_event {
	co_event_kind kind;
	uint64_t now_us; /* time of the call that produced the event */
	union {
		co_ev_od od;
		co_ev_sdo_srv sdo_srv;
		co_ev_sdo_cli sdo_cli;
		co_ev_store store;
		co_frame frame;
		co_ev_nmt nmt;
		co_ev_errctrl errctrl;
		co_ev_emcy emcy;
		co_ev_sync sync;
		co_ev_time time;
		co_ev_pdo pdo;
		co_ev_pdo_obj pdo_obj;
		co_ev_lss_master lss_master;
		co_ev_lss_slave lss_slave;
		co_ev_mgr mgr;
		co_ev_commfault commfault;
	} u;
} co_event;

#endif /* COGW_CORE_EVENT_H */
