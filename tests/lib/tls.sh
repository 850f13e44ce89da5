# Throwaway certificates for the TLS tests, made with the openssl command line (sourced; pure functions).
# shellcheck shell=bash

# make_ca DIR NAME: a self-signed test CA (EC P-256, valid 2 days) in DIR/NAME.pem with its key in DIR/NAME.key.
make_ca() {
  openssl req -x509 -newkey ec -pkeyopt ec_paramgen_curve:P-256 -nodes -keyout "$1/$2.key" -out "$1/$2.pem" \
    -days 2 -subj "/CN=$2 (tessera test CA)" -addext basicConstraints=critical,CA:TRUE \
    -addext keyUsage=critical,keyCertSign,cRLSign 2>/dev/null
}

# make_cert DIR CA NAME SAN USAGE: a leaf certificate DIR/NAME.pem (key DIR/NAME.key) signed by DIR/CA.pem, with
# subjectAltName SAN (e.g. "IP:127.0.0.1,DNS:localhost") and extendedKeyUsage USAGE (serverAuth or clientAuth).
make_cert() {
  local dir=$1 ca=$2 name=$3 san=$4 usage=$5
  openssl req -new -newkey ec -pkeyopt ec_paramgen_curve:P-256 -nodes -keyout "$dir/$name.key" -out "$dir/$name.csr" \
    -subj "/CN=$name" 2>/dev/null
  printf 'subjectAltName=%s\nextendedKeyUsage=%s\nbasicConstraints=CA:FALSE\n' "$san" "$usage" >"$dir/$name.ext"
  openssl x509 -req -in "$dir/$name.csr" -CA "$dir/$ca.pem" -CAkey "$dir/$ca.key" -CAcreateserial -days 2 \
    -extfile "$dir/$name.ext" -out "$dir/$name.pem" 2>/dev/null
  chmod 600 "$dir/$name.key"
}
