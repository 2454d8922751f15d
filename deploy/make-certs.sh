#!/bin/sh
# Make a private CA and certificates signed by it, for Zenoh's mutual TLS.
#
#   deploy/make-certs.sh DIR NAME[=SAN,SAN...] ...
#
# DIR/ca.pem and DIR/ca.key are created on first use and reused afterwards, so
# certificates for new hosts can be added later.  Each NAME gets DIR/NAME.pem
# and DIR/NAME.key (EC P-256, valid 825 days).  SANs are what a client checks
# the router's certificate against: give a router every name and address that
# clients put in their tls/ endpoints, e.g.
#
#   deploy/make-certs.sh certs router-a=DNS:broker.lan,IP:10.0.0.1 worker-1 worker-2
#
# Without SANs a certificate gets DNS:NAME (enough for a client).  Keep ca.key
# off the hosts: they need only ca.pem and their own NAME.pem and NAME.key.
set -eu
[ $# -ge 2 ] || { echo "usage: $0 DIR NAME[=SAN,SAN...] ..." >&2; exit 2; }
dir=$1; shift
mkdir -p "$dir"
umask 077
if [ ! -f "$dir/ca.pem" ]; then
    openssl req -x509 -newkey ec -pkeyopt ec_paramgen_curve:prime256v1 -nodes -days 3650 \
        -subj "/CN=coevo CA $(basename "$dir")" -keyout "$dir/ca.key" -out "$dir/ca.pem" \
        -addext "basicConstraints=critical,CA:TRUE" -addext "keyUsage=critical,keyCertSign,cRLSign" 2>/dev/null
fi
for spec in "$@"; do
    name=${spec%%=*}
    if [ "$name" = "$spec" ]; then san="DNS:$name"; else san=${spec#*=}; fi
    openssl req -newkey ec -pkeyopt ec_paramgen_curve:prime256v1 -nodes -subj "/CN=$name" \
        -keyout "$dir/$name.key" -out "$dir/$name.csr" 2>/dev/null
    ext=$(mktemp)
    printf 'basicConstraints=critical,CA:FALSE\nkeyUsage=critical,digitalSignature,keyEncipherment\nextendedKeyUsage=serverAuth,clientAuth\nsubjectAltName=%s\n' "$san" > "$ext"
    openssl x509 -req -in "$dir/$name.csr" -CA "$dir/ca.pem" -CAkey "$dir/ca.key" -CAcreateserial \
        -days 825 -extfile "$ext" -out "$dir/$name.pem" 2>/dev/null
    rm -f "$ext" "$dir/$name.csr"
    chmod 644 "$dir/$name.pem"
done
chmod 644 "$dir/ca.pem"
