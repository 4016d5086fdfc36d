/* SPDX-License-Identifier: MIT */
/*
 * apps/cosim/main.c - cosim, simulated CANopen slave devices on a SocketCAN
 * line (docs/cosim.md).
 *
 * One thread, one epoll loop, Redis-ae style: the CAN socket, one timerfd
 * armed at the earliest deadline of all nodes, a signalfd and the control
 * socket. The clock is read once per iteration and handed to every call.
 *
 * Several nodes share one socket. The kernel does not loop a socket's own
 * frames back to it, so frames one local node sends are also delivered to
 * the other local nodes here, as they would be on a real bus. They go
 * through a queue drained after each handler, never by a direct call from
 * one node's send callback into another node (which could then answer
 * into the first node while it is still inside its own call).
 */
#include <errno.h>
#include <getopt.h>
#include <limits.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/epoll.h>
#include <sys/signalfd.h>
#include <sys/socket.h>
#include <sys/timerfd.h>
#include <sys/un.h>
#include <time.h>
#include <unistd.h>

#include "apps/cosim/cosim.h"
#include "core/nmt.h"
#include "lines/socketcan.h"

#define MAX_NODES 16
#define LOCAL_QUEUE 1024

enum exit_code {
	EXIT_OK = 0,
	EXIT_RUNTIME = 1, /* CAN socket failed while running, epoll, ... */
	EXIT_USAGE = 2,   /* bad command line */
	EXIT_DEVICE = 3,  /* a device file or its stored values are bad */
	EXIT_CAN = 4,     /* the CAN interface cannot be opened */
};

struct local_frame {
	co_frame f;
	int from;
};

struct dev_arg {
	const char *file;
	cosim_device_opts opts;
};

struct app {
	can_port *port;
	cosim_node *nodes[MAX_NODES];
	int n_nodes;
	struct local_frame local[LOCAL_QUEUE];
	unsigned local_head, local_count;
	uint64_t local_dropped;
	bool quiet;
	bool quit;
};

static uint64_t mono_us(void)
{
	struct timespec ts;

	clock_gettime(CLOCK_MONOTONIC, &ts);
	return (uint64_t)ts.tv_sec * 1000000u + (uint64_t)ts.tv_nsec / 1000u;
}

static int node_index(const struct app *a, const cosim_node *n)
{
	for (int i = 0; i < a->n_nodes; i++)
		if (a->nodes[i] == n)
			return i;
	return -1;
}

/* cosim_out_fn: one node's frame leaves for the bus and the other nodes. */
static int out_frame(void *ctx, cosim_node *from, const co_frame *f, uint64_t now_us)
{
	struct app *a = ctx;
	int rc = can_port_send(a->port, f, now_us);

	if (a->n_nodes > 1) {
		if (a->local_count == LOCAL_QUEUE) {
			a->local_dropped++;
		} else {
			struct local_frame *l =
				&a->local[(a->local_head + a->local_count) % LOCAL_QUEUE];
			l->f = *f;
			/* nodes[] is filled while nodes are created; a node
			 * sends nothing before its first tick */
			l->from = node_index(a, from);
			a->local_count++;
		}
	}
	return rc;
}

static void drain_local(struct app *a, uint64_t now_us)
{
	/* Bounded: a pathological echo between two nodes cannot spin. */
	for (unsigned budget = 4 * LOCAL_QUEUE; a->local_count && budget; budget--) {
		struct local_frame l = a->local[a->local_head];
		a->local_head = (a->local_head + 1) % LOCAL_QUEUE;
		a->local_count--;
		for (int i = 0; i < a->n_nodes; i++)
			if (i != l.from)
				cosim_node_recv(a->nodes[i], &l.f, now_us);
	}
}

static void run_timers(struct app *a, uint64_t now_us)
{
	/* A tick may make another node's deadline due (local frames), so go
	 * round until nothing is due at this time. */
	for (int round = 0; round < 8; round++) {
		bool any = false;
		for (int i = 0; i < a->n_nodes; i++) {
			if (cosim_node_next_deadline(a->nodes[i]) <= now_us) {
				cosim_node_tick(a->nodes[i], now_us);
				any = true;
			}
		}
		drain_local(a, now_us);
		if (!any)
			break;
	}
}

static void arm_timer(struct app *a, int tfd, uint64_t now_us)
{
	uint64_t t = can_port_retry_at_us(a->port);
	struct itimerspec its = { 0 };

	for (int i = 0; i < a->n_nodes; i++) {
		uint64_t d = cosim_node_next_deadline(a->nodes[i]);
		if (d < t)
			t = d;
	}
	if (t != UINT64_MAX) {
		if (t <= now_us)
			t = now_us + 1; /* a zero it_value would disarm */
		its.it_value.tv_sec = (time_t)(t / 1000000u);
		its.it_value.tv_nsec = (long)(t % 1000000u) * 1000;
	}
	timerfd_settime(tfd, TFD_TIMER_ABSTIME, &its, NULL);
}

static int handle_can(struct app *a, uint64_t now_us)
{
	can_rx_item items[32];
	int n;

	while ((n = can_port_recv(a->port, items, 32, now_us)) > 0) {
		for (int k = 0; k < n; k++) {
			if (items[k].is_error) {
				if (items[k].error.state_changed)
					cosim_log(a->quiet, "CAN controller %s",
						  can_bus_state_to_string(items[k].error.state));
				continue;
			}
			for (int i = 0; i < a->n_nodes; i++)
				cosim_node_recv(a->nodes[i], &items[k].frame, now_us);
			drain_local(a, now_us);
		}
		if (n < 32)
			break;
	}
	if (n == -ENETDOWN) {
		/* The interface went down (ip link set ... down): a device on
		 * that bus waits for it to come back, as a real one would. */
		cosim_log(a->quiet, "CAN interface down");
	} else if (n < 0 && n != -EAGAIN) {
		cosim_log(false, "CAN receive failed: %s", strerror(-n));
		return n;
	}
	can_port_flush(a->port, now_us);
	return 0;
}

/* One datagram = one command, optionally "node N <command>". */
static void handle_control(struct app *a, int cfd, uint64_t now_us)
{
	char buf[512], reply[1024], one[256];
	struct sockaddr_un from;
	socklen_t flen = sizeof from;
	ssize_t len = recvfrom(cfd, buf, sizeof buf - 1, MSG_DONTWAIT, (struct sockaddr *)&from,
			       &flen);
	const char *cmd = buf;
	int only = -1;
	size_t used = 0;

	if (len < 0)
		return;
	buf[len] = 0;
	while (len > 0 && (buf[len - 1] == '\n' || buf[len - 1] == '\r'))
		buf[--len] = 0;
	reply[0] = 0;
	if (!strncmp(cmd, "node ", 5)) {
		char *end;
		long id = strtol(cmd + 5, &end, 10);
		if (end == cmd + 5 || *end != ' ' || id < 1 || id > 255) {
			snprintf(reply, sizeof reply, "error: node N COMMAND");
			goto answer;
		}
		only = (int)id;
		cmd = end + 1;
	}
	if (!strcmp(cmd, "quit")) {
		a->quit = true;
		snprintf(reply, sizeof reply, "ok quit");
		goto answer;
	}
	for (int i = 0; i < a->n_nodes; i++) {
		cosim_node *n = a->nodes[i];
		if (only >= 0 && cosim_node_config_id(n) != only &&
		    co_node_id(cosim_node_core(n)) != only)
			continue;
		cosim_node_command(n, cmd, now_us, one, sizeof one);
		int k = snprintf(reply + used, sizeof reply - used, "%s%s", used ? "; " : "", one);
		if (k > 0 && (size_t)k < sizeof reply - used)
			used += (size_t)k;
	}
	if (!used)
		snprintf(reply, sizeof reply, "error: no node %d here", only);
	drain_local(a, now_us);
answer:
	cosim_log(a->quiet, "control: %s -> %s", buf, reply);
	if (flen > sizeof(sa_family_t))
		sendto(cfd, reply, strlen(reply), MSG_DONTWAIT, (struct sockaddr *)&from, flen);
}

static int open_control(const char *path)
{
	struct sockaddr_un sa = { .sun_family = AF_UNIX };
	int fd;

	if (strlen(path) >= sizeof sa.sun_path) {
		errno = ENAMETOOLONG;
		return -1;
	}
	strcpy(sa.sun_path, path);
	fd = socket(AF_UNIX, SOCK_DGRAM | SOCK_CLOEXEC | SOCK_NONBLOCK, 0);
	if (fd < 0)
		return -1;
	unlink(path);
	if (bind(fd, (struct sockaddr *)&sa, sizeof sa) < 0) {
		int e = errno;
		close(fd);
		errno = e;
		return -1;
	}
	return fd;
}

static void usage(FILE *out)
{
	fputs("usage: cosim --interface IF --device FILE[:NODE] [--node-id N] [--serial N]\n"
	      "             [--device ...] [options]\n"
	      "\n"
	      "Simulated CANopen slave devices on a SocketCAN line, each described by a\n"
	      "JSON device file (etc/devices/*.json, format in docs/cosim.md).\n"
	      "\n"
	      "Devices (--device may repeat: several nodes in one process):\n"
	      "  -i, --interface IF     CAN interface (vcan0, can0)\n"
	      "  -d, --device FILE[:N]  add a node from FILE, optionally with node-ID N\n"
	      "  -n, --node-id N        node-ID of the last --device (1..127, 255 = LSS\n"
	      "                         unconfigured)\n"
	      "  -s, --serial N         1018h:4 serial number of the last --device\n"
	      "      --nv DIR           non-volatile memory: 1010h \"save\" and LSS store\n"
	      "                         write DIR/<device>-<node>.{comm,app,lss}; the next\n"
	      "                         start loads them\n"
	      "      --autostart        enter OPERATIONAL after boot-up without a master\n"
	      "      --loopback         echo outputs into inputs (device file \"loopback\")\n"
	      "      --sdo-timeout MS   SDO server timeout per frame (default 1000): raise it\n"
	      "                         where the peer can stall for longer (slow test VMs)\n"
	      "\n"
	      "Faults (all nodes; also switchable at run time, see --control):\n"
	      "      --silent           send nothing, hear nothing (cable pulled)\n"
	      "      --hb-stop          no heartbeats (boot-up still goes out)\n"
	      "      --sdo-silent       no SDO answers\n"
	      "      --sdo-abort CODE   answer every SDO request with this abort code\n"
	      "      --sdo-delay MS     send SDO answers MS milliseconds late\n"
	      "      --sdo-lenient      accept printed-sheet frames: too small sizes in\n"
	      "                         expedited writes (2Bh for 4 bytes), reversed \"save\"\n"
	      "      --pdo-badlen       TPDOs one byte short\n"
	      "      SIGUSR1            toggles --hb-stop\n"
	      "\n"
	      "Control:\n"
	      "  -c, --control PATH     UNIX datagram socket for commands, one per datagram,\n"
	      "                         answered \"ok ...\" or \"error: ...\" to the sender:\n"
	      "      hb stop|start            silent on|off\n"
	      "      sdo silent on|off        sdo abort CODE [0xINDEX[:SUB]] | sdo abort off\n"
	      "      sdo delay MS             sdo lenient on|off\n"
	      "      pdo badlen on|off        emcy CODE [REGISTER] | emcy clear\n"
	      "      pressure VALUE|off       signal NAME VALUE|off  (raw signal value)\n"
	      "      set 0xINDEX:SUB VALUE    get 0xINDEX:SUB\n"
	      "      nmt start|stop|preop|reset-node|reset-comm\n"
	      "      loopback on|off          status          quit\n"
	      "      prefix \"node N \" to address one node (default: all)\n"
	      "  -q, --quiet            no log lines on stderr\n"
	      "  -h, --help             this text\n"
	      "\n"
	      "Exit status: 0 clean exit (SIGTERM, SIGINT, quit), 1 runtime failure,\n"
	      "2 bad command line, 3 bad device file or stored values, 4 CAN interface\n"
	      "cannot be opened.\n",
	      out);
}

static bool parse_int(const char *s, long min, long max, long *out)
{
	char *end;
	long v;

	errno = 0;
	v = strtol(s, &end, 0);
	if (errno || end == s || *end || v < min || v > max)
		return false;
	*out = v;
	return true;
}

/* "etc/devices/sti-pressure.json" -> "sti-pressure-1" */
static void nv_key(char *out, size_t n, const char *file, unsigned node)
{
	const char *base = strrchr(file, '/');
	size_t len;

	base = base ? base + 1 : file;
	len = strlen(base);
	if (len > 5 && !strcmp(base + len - 5, ".json"))
		len -= 5;
	if (len > 64)
		len = 64;
	snprintf(out, n, "%.*s-%u", (int)len, base, node);
}

enum {
	OPT_NV = 1000,
	OPT_AUTOSTART,
	OPT_LOOPBACK,
	OPT_SILENT,
	OPT_HB_STOP,
	OPT_SDO_SILENT,
	OPT_SDO_ABORT,
	OPT_SDO_DELAY,
	OPT_SDO_LENIENT,
	OPT_PDO_BADLEN,
	OPT_SDO_TIMEOUT,
};

int main(int argc, char **argv)
{
	static const struct option longopts[] = {
		{ "interface", required_argument, NULL, 'i' },
		{ "device", required_argument, NULL, 'd' },
		{ "node-id", required_argument, NULL, 'n' },
		{ "serial", required_argument, NULL, 's' },
		{ "control", required_argument, NULL, 'c' },
		{ "quiet", no_argument, NULL, 'q' },
		{ "help", no_argument, NULL, 'h' },
		{ "nv", required_argument, NULL, OPT_NV },
		{ "autostart", no_argument, NULL, OPT_AUTOSTART },
		{ "loopback", no_argument, NULL, OPT_LOOPBACK },
		{ "silent", no_argument, NULL, OPT_SILENT },
		{ "hb-stop", no_argument, NULL, OPT_HB_STOP },
		{ "sdo-silent", no_argument, NULL, OPT_SDO_SILENT },
		{ "sdo-abort", required_argument, NULL, OPT_SDO_ABORT },
		{ "sdo-delay", required_argument, NULL, OPT_SDO_DELAY },
		{ "sdo-lenient", no_argument, NULL, OPT_SDO_LENIENT },
		{ "pdo-badlen", no_argument, NULL, OPT_PDO_BADLEN },
		{ "sdo-timeout", required_argument, NULL, OPT_SDO_TIMEOUT },
		{ NULL, 0, NULL, 0 },
	};
	static struct app app; /* large (local queue): not on the stack */
	struct dev_arg devs[MAX_NODES];
	int n_devs = 0, opt, rc = EXIT_OK;
	const char *ifname = NULL, *nv_dir = NULL, *control = NULL;
	bool autostart = false, loopback = false;
	uint32_t sdo_timeout_ms = 0; /* core default */
	cosim_faults faults = { 0 };
	long v;
	char err[COSIM_ERR_MAX];
	int efd = -1, tfd = -1, sfd = -1, cfd = -1;
	sigset_t mask;

	while ((opt = getopt_long(argc, argv, "i:d:n:s:c:qh", longopts, NULL)) != -1) {
		switch (opt) {
		case 'i':
			ifname = optarg;
			break;
		case 'd': {
			if (n_devs == MAX_NODES) {
				fprintf(stderr, "cosim: at most %d devices\n", MAX_NODES);
				return EXIT_USAGE;
			}
			struct dev_arg *d = &devs[n_devs++];
			char *colon = strrchr(optarg, ':');
			d->file = optarg;
			d->opts.node_id = -1;
			d->opts.serial = -1;
			if (colon && parse_int(colon + 1, 1, 255, &v)) {
				*colon = 0;
				d->opts.node_id = (int)v;
			}
			break;
		}
		case 'n':
		case 's':
			if (!n_devs) {
				fprintf(stderr, "cosim: --%s applies to the --device before it\n",
					opt == 'n' ? "node-id" : "serial");
				return EXIT_USAGE;
			}
			if (opt == 'n') {
				if (!parse_int(optarg, 1, 255, &v) || (v > 127 && v != 255)) {
					fprintf(stderr, "cosim: --node-id %s: 1..127 or 255\n",
						optarg);
					return EXIT_USAGE;
				}
				devs[n_devs - 1].opts.node_id = (int)v;
			} else {
				if (!parse_int(optarg, 0, 0xFFFFFFFFL, &v)) {
					fprintf(stderr, "cosim: --serial %s: 0..0xFFFFFFFF\n",
						optarg);
					return EXIT_USAGE;
				}
				devs[n_devs - 1].opts.serial = v;
			}
			break;
		case 'c':
			control = optarg;
			break;
		case 'q':
			app.quiet = true;
			break;
		case 'h':
			usage(stdout);
			return EXIT_OK;
		case OPT_NV:
			nv_dir = optarg;
			break;
		case OPT_AUTOSTART:
			autostart = true;
			break;
		case OPT_LOOPBACK:
			loopback = true;
			break;
		case OPT_SILENT:
			faults.silent = true;
			break;
		case OPT_HB_STOP:
			faults.hb_stop = true;
			break;
		case OPT_SDO_SILENT:
			faults.sdo_silent = true;
			break;
		case OPT_SDO_ABORT:
			if (!parse_int(optarg, 1, 0xFFFFFFFFL, &v)) {
				fprintf(stderr, "cosim: --sdo-abort %s: an abort code\n", optarg);
				return EXIT_USAGE;
			}
			faults.sdo_abort = (uint32_t)v;
			break;
		case OPT_SDO_DELAY:
			if (!parse_int(optarg, 0, 600000, &v)) {
				fprintf(stderr, "cosim: --sdo-delay %s: 0..600000 ms\n", optarg);
				return EXIT_USAGE;
			}
			faults.sdo_delay_ms = (uint32_t)v;
			break;
		case OPT_SDO_LENIENT:
			faults.sdo_lenient = true;
			break;
		case OPT_SDO_TIMEOUT:
			if (!parse_int(optarg, 1, 600000, &v)) {
				fprintf(stderr, "cosim: --sdo-timeout %s: 1..600000 ms\n", optarg);
				return EXIT_USAGE;
			}
			sdo_timeout_ms = (uint32_t)v;
			break;
		case OPT_PDO_BADLEN:
			faults.pdo_badlen = true;
			break;
		default:
			usage(stderr);
			return EXIT_USAGE;
		}
	}
	if (optind < argc || !ifname || !n_devs) {
		fprintf(stderr, "cosim: %s\n",
			optind < argc ? "unexpected argument"
			: !ifname     ? "--interface is required"
				      : "at least one --device is required");
		usage(stderr);
		return EXIT_USAGE;
	}

	/* Signals first: a SIGTERM during start-up is not lost. */
	sigemptyset(&mask);
	sigaddset(&mask, SIGTERM);
	sigaddset(&mask, SIGINT);
	sigaddset(&mask, SIGUSR1);
	sigaddset(&mask, SIGHUP);
	sigprocmask(SIG_BLOCK, &mask, NULL);
	signal(SIGPIPE, SIG_IGN);

	uint64_t now = mono_us();
	for (int i = 0; i < n_devs; i++) {
		cosim_device dev;
		cosim_node_config nc = { 0 };
		char key[128];
		if (cosim_device_load(&dev, devs[i].file, &devs[i].opts, err, sizeof err)) {
			fprintf(stderr, "cosim: %s\n", err);
			rc = EXIT_DEVICE;
			goto out;
		}
		for (int k = 0; k < app.n_nodes; k++) {
			if (cosim_node_config_id(app.nodes[k]) == dev.node_id &&
			    dev.node_id != 255) {
				fprintf(stderr, "cosim: %s: node-ID %u is used twice\n",
					devs[i].file, dev.node_id);
				cosim_device_free(&dev);
				rc = EXIT_USAGE;
				goto out;
			}
		}
		if (loopback)
			dev.loopback_enabled = true;
		nv_key(key, sizeof key, devs[i].file, dev.node_id);
		nc.dev = &dev;
		nc.nv_dir = nv_dir;
		nc.nv_key = key;
		nc.faults = faults;
		nc.autostart = autostart;
		nc.sdo_timeout_ms = sdo_timeout_ms;
		nc.quiet = app.quiet;
		nc.out = out_frame;
		nc.out_ctx = &app;
		nc.now_us = now;
		if (cosim_node_create(&app.nodes[app.n_nodes], &nc, err, sizeof err)) {
			fprintf(stderr, "cosim: %s\n", err);
			rc = EXIT_DEVICE;
			goto out;
		}
		app.n_nodes++;
	}

	/* After the device files: a bad file is reported as such (exit 3)
	 * even where there is no CAN. Nodes send nothing before their first
	 * tick, in the loop below. */
	can_port_config pc = { .ifname = ifname, .bitrate = 125000 };
	const char *what = NULL;
	int prc = can_port_open(&app.port, &pc, &what);
	if (prc) {
		fprintf(stderr, "cosim: %s: %s: %s\n", ifname, what ? what : "open",
			strerror(-prc));
		rc = EXIT_CAN;
		goto out;
	}

	efd = epoll_create1(EPOLL_CLOEXEC);
	tfd = timerfd_create(CLOCK_MONOTONIC, TFD_CLOEXEC | TFD_NONBLOCK);
	sfd = signalfd(-1, &mask, SFD_CLOEXEC | SFD_NONBLOCK);
	if (efd < 0 || tfd < 0 || sfd < 0) {
		fprintf(stderr, "cosim: epoll/timerfd/signalfd: %s\n", strerror(errno));
		rc = EXIT_RUNTIME;
		goto out;
	}
	if (control) {
		cfd = open_control(control);
		if (cfd < 0) {
			fprintf(stderr, "cosim: --control %s: %s\n", control, strerror(errno));
			rc = EXIT_USAGE;
			goto out;
		}
	}
	struct epoll_event ev = { .events = EPOLLIN };
	ev.data.fd = can_port_fd(app.port);
	epoll_ctl(efd, EPOLL_CTL_ADD, ev.data.fd, &ev);
	ev.data.fd = tfd;
	epoll_ctl(efd, EPOLL_CTL_ADD, tfd, &ev);
	ev.data.fd = sfd;
	epoll_ctl(efd, EPOLL_CTL_ADD, sfd, &ev);
	if (cfd >= 0) {
		ev.data.fd = cfd;
		epoll_ctl(efd, EPOLL_CTL_ADD, cfd, &ev);
	}
	cosim_log(app.quiet, "%d node(s) on %s%s%s", app.n_nodes, ifname,
		  control ? ", control " : "", control ? control : "");

	bool want_out = false;
	while (!app.quit) {
		struct epoll_event evs[8];

		now = mono_us();
		run_timers(&app, now);
		can_port_flush(app.port, now);
		bool w = can_port_wants_writable(app.port);
		if (w != want_out) {
			struct epoll_event ce = { .events = EPOLLIN | (w ? EPOLLOUT : 0),
						  .data.fd = can_port_fd(app.port) };
			epoll_ctl(efd, EPOLL_CTL_MOD, ce.data.fd, &ce);
			want_out = w;
		}
		arm_timer(&app, tfd, now);

		int nev = epoll_wait(efd, evs, 8, -1);
		if (nev < 0) {
			if (errno == EINTR)
				continue;
			fprintf(stderr, "cosim: epoll_wait: %s\n", strerror(errno));
			rc = EXIT_RUNTIME;
			break;
		}
		now = mono_us();
		for (int k = 0; k < nev; k++) {
			int fd = evs[k].data.fd;
			if (fd == tfd) {
				uint64_t exp;
				while (read(tfd, &exp, sizeof exp) > 0)
					;
			} else if (fd == sfd) {
				struct signalfd_siginfo si;
				while (read(sfd, &si, sizeof si) == sizeof si) {
					if (si.ssi_signo == SIGUSR1) {
						for (int i = 0; i < app.n_nodes; i++) {
							cosim_faults *f = cosim_node_faults(
								app.nodes[i]);
							f->hb_stop = !f->hb_stop;
							cosim_log(
								app.quiet,
								"SIGUSR1: node %u heartbeat %s",
								cosim_node_config_id(app.nodes[i]),
								f->hb_stop ? "stopped" : "running");
						}
					} else if (si.ssi_signo != SIGHUP) {
						cosim_log(app.quiet, "%s: exiting",
							  strsignal((int)si.ssi_signo));
						app.quit = true;
					}
				}
			} else if (fd == cfd) {
				handle_control(&app, cfd, now);
			} else if (fd == can_port_fd(app.port)) {
				if ((evs[k].events & EPOLLIN) && handle_can(&app, now)) {
					rc = EXIT_RUNTIME;
					app.quit = true;
				}
				if (evs[k].events & EPOLLOUT)
					can_port_flush(app.port, now);
			}
		}
	}
	/* Frames still queued (an answer to the last request) go out first. */
	can_port_flush(app.port, mono_us());

out:
	if (app.local_dropped)
		cosim_log(app.quiet, "%llu local frames dropped (queue full)",
			  (unsigned long long)app.local_dropped);
	for (int i = 0; i < app.n_nodes; i++)
		cosim_node_destroy(app.nodes[i]);
	can_port_close(app.port);
	if (cfd >= 0) {
		close(cfd);
		unlink(control);
	}
	if (sfd >= 0)
		close(sfd);
	if (tfd >= 0)
		close(tfd);
	if (efd >= 0)
		close(efd);
	return rc;
}
