#!/usr/bin/env python3
"""A static file server whose link is slow: files under the given path prefixes arrive at
RATE bits per second after LATENCY milliseconds (each response on its own, as one
connection of a link of that rate delivers it); everything else is served at once. A file
with a FILE.gz beside it is sent gzipped to a client that accepts gzip, as a web server
configured to compress it would send it (browsers decompress it as it arrives).

usage: throttled_server.py DIR PORT [--rate 50e6] [--latency 20] [--slow data/,pkg/]
"""
import argparse
import functools
import http.server
import os
import time

CHUNK = 16 * 1024


class Handler(http.server.SimpleHTTPRequestHandler):
    rate = 50e6
    latency = 0.02
    slow = ("/data/", "/pkg/")

    def is_slow(self):
        return self.path.split("?", 1)[0].startswith(self.slow)

    def send_head(self):
        if self.is_slow():
            time.sleep(self.latency)
        path = self.translate_path(self.path)
        if "gzip" in self.headers.get("Accept-Encoding", "") and os.path.isfile(path + ".gz"):
            f = open(path + ".gz", "rb")
            self.send_response(200)
            self.send_header("Content-Type", self.guess_type(path))
            self.send_header("Content-Encoding", "gzip")
            self.send_header("Content-Length", str(os.fstat(f.fileno()).st_size))
            self.end_headers()
            return f
        return super().send_head()

    def copyfile(self, source, outputfile):
        if not self.is_slow():
            return super().copyfile(source, outputfile)
        # Paced against the clock from the first byte, so a late write catches up.
        start, sent = time.monotonic(), 0
        while True:
            chunk = source.read(CHUNK)
            if not chunk:
                break
            outputfile.write(chunk)
            sent += len(chunk)
            ahead = start + 8 * sent / self.rate - time.monotonic()
            if ahead > 0:
                time.sleep(ahead)

    def log_message(self, *args):
        pass


def main():
    a = argparse.ArgumentParser()
    a.add_argument("dir")
    a.add_argument("port", type=int)
    a.add_argument("--rate", type=float, default=50e6, help="bits per second")
    a.add_argument("--latency", type=float, default=20, help="milliseconds before a response")
    a.add_argument("--slow", default="data/,pkg/", help="path prefixes served at RATE")
    o = a.parse_args()
    Handler.rate = o.rate
    Handler.latency = o.latency / 1000
    Handler.slow = tuple("/" + p.lstrip("/") for p in o.slow.split(",") if p)
    handler = functools.partial(Handler, directory=o.dir)
    with http.server.ThreadingHTTPServer(("127.0.0.1", o.port), handler) as server:
        server.serve_forever()


if __name__ == "__main__":
    main()
