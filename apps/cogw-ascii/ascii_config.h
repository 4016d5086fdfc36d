/* SPDX-License-Identifier: MIT */
/*
 * apps/cogw-ascii/ascii_config.h - the ASCII gateway's own configuration
 * (a JSON file, reference in docs/ascii.md "Configuration"), validated
 * strictly like cogwd's (apps/common/config.c): unknown keys, wrong types
 * and values out of range are refused with one message
 * "file: json.path: reason" and the gateway does not start.
 */
#ifndef COGW_ASCII_CONFIG_H
#define COGW_ASCII_CONFIG_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

typedef struct ascii_config {
	char daemon_config[256]; /* cogwd's file: instance, networks, access rules;
	                          * "" = cogwd's embedded default */
	char unix_socket[108];   /* "" = none (socket activation may still give one) */
	unsigned unix_mode;      /* permissions of the socket file (0660) */
	bool tcp;                /* a TCP listener is configured */
	char tcp_address[64];    /* numeric IPv4/IPv6 address (127.0.0.1) */
	uint16_t tcp_port;
	uint8_t tcp_access;          /* cogw_access_level of TCP peers (read) */
	unsigned max_connections;    /* at once, all listeners (64) */
	unsigned max_line;           /* bytes of one command line (65536) */
	unsigned max_outstanding;    /* commands of one connection under way (4) */
	unsigned max_output;         /* unread answer bytes before a peer is
	                             * no longer served (4 MiB) */
	unsigned sdo_timeout_ms;     /* a connection's initial SDO timeout (1000) */
	bool sdo_block;              /* a connection's initial sdo_block (false) */
	int default_network;         /* a connection's initial net: 1..127, 0 = none
	                             * set (ERROR: 104 until `set network`), -1 =
	                             * the network of the daemon's line 0 */
	unsigned route_line;         /* line asked for networks not attached (0) */
	unsigned request_timeout_ms; /* mailbox exchange of one command (60000) */
} ascii_config;

void ascii_config_defaults(ascii_config *c);
/* Load path (NULL = defaults only). 0, or -EINVAL/-ENOENT/-EIO with one
 * line in err. */
int ascii_config_load_file(ascii_config *c, const char *path, char *err, size_t errlen);
int ascii_config_load_string(ascii_config *c, const char *json, const char *source, char *err,
			     size_t errlen);

#endif /* COGW_ASCII_CONFIG_H */
