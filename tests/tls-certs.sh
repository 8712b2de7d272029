#!/bin/sh
# tls-certs.sh - test certificates for TLS (daemon/tls.h), made at test time in a few ms:
#   tls-certs.sh DIR SAN
# writes into DIR: ca.pem/ca.key (a CA), server.pem/server.key (a server certificate the CA
# signed, subjectAltName SAN, e.g. "IP:127.0.0.1,DNS:localhost") and other-ca.pem (a CA that
# signed nothing here: the wrong CA). P-256 keys, valid two days. Exits 77 without openssl.
set -eu
command -v openssl >/dev/null || { echo "tls-certs.sh: no openssl" >&2; exit 77; }
dir=$1 san=$2
ec="-newkey ec -pkeyopt ec_paramgen_curve:P-256 -nodes -days 2"
cd "$dir"
openssl req -x509 $ec -keyout ca.key -out ca.pem -subj /CN=gonio-test-ca 2>/dev/null
openssl req -x509 $ec -keyout other-ca.key -out other-ca.pem -subj /CN=gonio-other-ca 2>/dev/null
openssl req -x509 $ec -keyout server.key -out server.pem -subj /CN=goniod -CA ca.pem \
        -CAkey ca.key -addext "subjectAltName=$san" -addext basicConstraints=critical,CA:FALSE \
        2>/dev/null
