#!/usr/bin/env bash
# make_certs.sh DIR [SAN]: test certificates for the farm, made fresh at test
# time (nothing secret is kept in the repository). In DIR:
#   ca.pem ca.key          a CA
#   server.pem server.key  the coordinator, for 127.0.0.1, ::1 and localhost,
#                          and SAN when given ("DNS:coordinator", for the
#                          containers' workers; comma-separated)
#   client.pem client.key  a client certificate (a worker's, for mutual TLS)
#   other-ca.pem           a second CA that signed nothing here
# EC P-256 keys: fast to make. docs/farm.md "Security" shows the same steps.
set -euo pipefail
dir=$1
extra=${2:+,$2}
mkdir -p "$dir"
cd "$dir"
ec="-newkey ec -pkeyopt ec_paramgen_curve:prime256v1 -nodes"
# shellcheck disable=SC2086
openssl req -x509 $ec -keyout ca.key -out ca.pem -days 2 -subj "/CN=Locus test CA" 2>/dev/null
# shellcheck disable=SC2086
openssl req -x509 $ec -keyout other-ca.key -out other-ca.pem -days 2 -subj "/CN=Another CA" 2>/dev/null

printf 'subjectAltName=IP:127.0.0.1,IP:::1,DNS:localhost%s\nextendedKeyUsage=serverAuth\n' "$extra" >server.ext
# shellcheck disable=SC2086
openssl req $ec -keyout server.key -out server.csr -subj "/CN=localhost" 2>/dev/null
openssl x509 -req -in server.csr -CA ca.pem -CAkey ca.key -CAcreateserial -days 2 \
  -extfile server.ext -out server.pem 2>/dev/null

printf 'extendedKeyUsage=clientAuth\n' >client.ext
# shellcheck disable=SC2086
openssl req $ec -keyout client.key -out client.csr -subj "/CN=locus-worker" 2>/dev/null
openssl x509 -req -in client.csr -CA ca.pem -CAkey ca.key -CAcreateserial -days 2 \
  -extfile client.ext -out client.pem 2>/dev/null
chmod 600 ./*.key
rm -f ./*.csr ./*.ext ./*.srl
