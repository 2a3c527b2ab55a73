#!/usr/bin/env python3
# A local RFC 3161 time-stamping authority for the evidence tests, made with `openssl ts`:
# creates a CA and a TSA certificate (extendedKeyUsage timeStamping) in DIR, then answers
# POSTed timestamp queries on 127.0.0.1 at a free port, written to DIR/port once listening.
# Usage: local_tsa.py DIR
import http.server, os, subprocess, sys, tempfile

d = sys.argv[1]
os.makedirs(d, exist_ok=True)
def sh(*args):
    subprocess.run(args, check=True, cwd=d, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)

open(os.path.join(d, "ext.cnf"), "w").write(
    "[tsa_ext]\nbasicConstraints=CA:FALSE\nkeyUsage=critical,digitalSignature\n"
    "extendedKeyUsage=critical,timeStamping\n")
sh("openssl", "req", "-x509", "-newkey", "rsa:2048", "-nodes", "-keyout", "ca.key", "-out", "ca.pem",
   "-days", "30", "-subj", "/CN=meshmark test CA")
sh("openssl", "req", "-newkey", "rsa:2048", "-nodes", "-keyout", "tsa.key", "-out", "tsa.csr",
   "-subj", "/CN=meshmark test TSA")
sh("openssl", "x509", "-req", "-in", "tsa.csr", "-CA", "ca.pem", "-CAkey", "ca.key", "-CAcreateserial",
   "-out", "tsa.pem", "-days", "30", "-extfile", "ext.cnf", "-extensions", "tsa_ext")
open(os.path.join(d, "serial"), "w").write("01\n")
open(os.path.join(d, "tsa.cnf"), "w").write(f"""[tsa]
default_tsa = tsa1
[tsa1]
dir = {d}
serial = $dir/serial
signer_cert = $dir/tsa.pem
signer_key = $dir/tsa.key
certs = $dir/ca.pem
signer_digest = sha256
default_policy = 1.2.3.4.1
digests = sha256, sha384, sha512
accuracy = secs:1
ordering = yes
tsa_name = no
ess_cert_id_chain = no
ess_cert_id_alg = sha256
""")

class Handler(http.server.BaseHTTPRequestHandler):
    def do_POST(self):
        body = self.rfile.read(int(self.headers.get("Content-Length", 0)))
        with tempfile.TemporaryDirectory() as t:
            q, r = os.path.join(t, "q.tsq"), os.path.join(t, "r.tsr")
            open(q, "wb").write(body)
            ok = subprocess.run(["openssl", "ts", "-reply", "-config", os.path.join(d, "tsa.cnf"), "-queryfile", q,
                                 "-out", r], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL).returncode == 0
            reply = open(r, "rb").read() if ok else b""
        self.send_response(200 if ok else 400)
        self.send_header("Content-Type", "application/timestamp-reply")
        self.send_header("Content-Length", str(len(reply)))
        self.end_headers()
        self.wfile.write(reply)
    def log_message(self, *a):
        pass

server = http.server.HTTPServer(("127.0.0.1", 0), Handler)
open(os.path.join(d, "port.tmp"), "w").write(str(server.server_port))
os.replace(os.path.join(d, "port.tmp"), os.path.join(d, "port"))
server.serve_forever()
