"""Pure-numpy PCD reader and writer (ascii, binary, binary_compressed) with an own LZF codec.

PCD is PCL's point cloud format
(https://pointclouds.org/documentation/tutorials/pcd_file_format.html).
`binary_compressed` stores, after the header, two little-endian uint32 (compressed size,
uncompressed size) and an LZF stream whose uncompressed content is the cloud in
structure-of-arrays order (all values of the first field, then all of the second, ...).
LZF (Marc Lehmann's liblzf) is a byte-oriented LZ77 variant: a control byte below 32 starts a
literal run of ctrl+1 bytes; otherwise its top 3 bits are a length (7 means "add the next
byte") and its low 5 bits plus the next byte are a back-reference offset.

The writer exists for tests and synthetic fixtures; the pipeline writes its PCDs with PCL.
"""

import collections

import numpy as np

_TYPE_CODES = {('F', 4): 'f4', ('F', 8): 'f8',
               ('U', 1): 'u1', ('U', 2): 'u2', ('U', 4): 'u4', ('U', 8): 'u8',
               ('I', 1): 'i1', ('I', 2): 'i2', ('I', 4): 'i4', ('I', 8): 'i8'}


class PcdError(ValueError):
    """A PCD file that cannot be parsed; the message names the file and the problem."""


# ---------------------------------------------------------------------------------------------
# LZF
# ---------------------------------------------------------------------------------------------
def lzf_decompress(data, out_len):
    """Decompresses an LZF stream into exactly `out_len` bytes (raises PcdError otherwise)."""
    data = bytes(data)
    out = bytearray(out_len)
    ip, op, n = 0, 0, len(data)
    try:
        while ip < n:
            ctrl = data[ip]
            ip += 1
            if ctrl < 32:
                length = ctrl + 1
                if ip + length > n or op + length > out_len:
                    raise PcdError('LZF literal run past the end of the buffer')
                out[op:op + length] = data[ip:ip + length]
                ip += length
                op += length
                continue
            length = ctrl >> 5
            if length == 7:
                length += data[ip]
                ip += 1
            ref = op - ((ctrl & 0x1f) << 8) - 1 - data[ip]
            ip += 1
            length += 2
            if ref < 0 or op + length > out_len:
                raise PcdError('LZF back-reference out of range')
            dist = op - ref
            if dist >= length:
                out[op:op + length] = out[ref:ref + length]
            else:  # overlapping copy repeats the last `dist` bytes
                pattern = bytes(out[ref:op])
                out[op:op + length] = (pattern * (length // dist + 1))[:length]
            op += length
    except IndexError:
        raise PcdError('LZF stream truncated') from None
    if op != out_len:
        raise PcdError('LZF stream gives %d bytes, header says %d' % (op, out_len))
    return bytes(out)


def lzf_compress(data):
    """Greedy LZF compressor (hash of 3-byte prefixes); output is readable by liblzf/PCL."""
    data = bytes(data)
    n = len(data)
    out = bytearray()
    literal = bytearray()
    table = {}

    def flush_literal():
        for k in range(0, len(literal), 32):
            chunk = literal[k:k + 32]
            out.append(len(chunk) - 1)
            out.extend(chunk)
        literal.clear()

    i = 0
    while i < n:
        if i + 2 < n:
            key = data[i:i + 3]
            ref = table.get(key)
            table[key] = i
            if ref is not None and i - ref - 1 < 8192:
                max_len = min(264, n - i)
                length = 3
                while length < max_len and data[ref + length] == data[i + length]:
                    length += 1
                flush_literal()
                offset = i - ref - 1
                code = length - 2
                if code < 7:
                    out.append((code << 5) | (offset >> 8))
                else:
                    out.append((7 << 5) | (offset >> 8))
                    out.append(code - 7)
                out.append(offset & 0xff)
                i += length
                continue
        literal.append(data[i])
        i += 1
    flush_literal()
    return bytes(out)


# ---------------------------------------------------------------------------------------------
# Reading
# ---------------------------------------------------------------------------------------------
PcdHeader = collections.namedtuple('PcdHeader', 'fields sizes types counts width height points '
                                   'viewpoint data')


def _parse_header(raw, path):
    header = {}
    offset = 0
    while True:
        end = raw.find(b'\n', offset)
        if end < 0:
            raise PcdError('%s: header has no DATA line' % path)
        line = raw[offset:end].decode('ascii', 'replace').strip()
        offset = end + 1
        if not line or line.startswith('#'):
            continue
        key, _, value = line.partition(' ')
        header[key.upper()] = value.split()
        if key.upper() == 'DATA':
            break
    try:
        fields = header['FIELDS']
        sizes = [int(v) for v in header['SIZE']]
        types = [v.upper() for v in header['TYPE']]
        counts = [int(v) for v in header.get('COUNT', ['1'] * len(fields))]
        width = int(header['WIDTH'][0])
        height = int(header.get('HEIGHT', ['1'])[0])
        points = int(header.get('POINTS', [str(width * height)])[0])
        viewpoint = [float(v) for v in header.get('VIEWPOINT', '0 0 0 1 0 0 0'.split())]
        data = header['DATA'][0].lower()
    except (KeyError, IndexError, ValueError) as error:
        raise PcdError('%s: malformed header (%s)' % (path, error)) from None
    if not (len(fields) == len(sizes) == len(types) == len(counts)):
        raise PcdError('%s: FIELDS/SIZE/TYPE/COUNT lengths differ' % path)
    for t, s in zip(types, sizes):
        if (t, s) not in _TYPE_CODES:
            raise PcdError('%s: unsupported field type %s%d' % (path, t, s))
    if data not in ('ascii', 'binary', 'binary_compressed'):
        raise PcdError('%s: unsupported DATA %s' % (path, data))
    return PcdHeader(fields, sizes, types, counts, width, height, points, viewpoint,
                     data), offset


def _unique_names(fields):
    seen = collections.Counter()
    names = []
    for f in fields:
        names.append(f if seen[f] == 0 else '%s_%d' % (f, seen[f]))
        seen[f] += 1
    return names


def read_pcd_header(path):
    """Reads only the header (cheap: used for point counts of many submaps)."""
    with open(path, 'rb') as f:
        raw = f.read(4096)
    return _parse_header(raw, path)[0]


def read_pcd(path):
    """Reads a PCD file into an ordered dict field name -> numpy array.

    Arrays have shape (N,) for COUNT 1 and (N, COUNT) otherwise; padding fields named `_`
    are dropped. Raises PcdError with the file name on any inconsistency.
    """
    with open(path, 'rb') as f:
        raw = f.read()
    h, offset = _parse_header(raw, path)
    n = h.points
    names = _unique_names(h.fields)
    dtypes = [np.dtype('<' + _TYPE_CODES[(t, s)]) for t, s in zip(h.types, h.sizes)]
    body = raw[offset:]
    columns = collections.OrderedDict()
    if h.data == 'ascii':
        values = body.decode('ascii', 'replace').split()
        per_point = sum(h.counts)
        if len(values) < n * per_point:
            raise PcdError('%s: ascii body has %d values, expected %d'
                           % (path, len(values), n * per_point))
        table = np.array(values[:n * per_point], dtype=np.float64).reshape(n, per_point)
        col = 0
        for name, dt, c in zip(names, dtypes, h.counts):
            block = table[:, col:col + c]
            col += c
            columns[name] = (block[:, 0] if c == 1 else block).astype(dt)
    elif h.data == 'binary':
        structured = np.dtype([(name, dt, (c,)) if c > 1 else (name, dt)
                               for name, dt, c in zip(names, dtypes, h.counts)])
        if len(body) < n * structured.itemsize:
            raise PcdError('%s: binary body truncated (%d bytes, expected %d)'
                           % (path, len(body), n * structured.itemsize))
        array = np.frombuffer(body, dtype=structured, count=n)
        for name in names:
            columns[name] = np.array(array[name])
    else:
        if len(body) < 8:
            raise PcdError('%s: binary_compressed body truncated' % path)
        compressed_size, uncompressed_size = np.frombuffer(body[:8], dtype='<u4')
        compressed = body[8:8 + int(compressed_size)]
        if len(compressed) != compressed_size:
            raise PcdError('%s: compressed body truncated' % path)
        expected = sum(dt.itemsize * c for dt, c in zip(dtypes, h.counts)) * n
        if uncompressed_size != expected:
            raise PcdError('%s: uncompressed size %d, expected %d'
                           % (path, uncompressed_size, expected))
        try:
            plain = lzf_decompress(compressed, int(uncompressed_size)) if expected else b''
        except PcdError as error:
            raise PcdError('%s: %s' % (path, error)) from None
        pos = 0
        for name, dt, c in zip(names, dtypes, h.counts):
            nbytes = dt.itemsize * c * n
            block = np.frombuffer(plain[pos:pos + nbytes], dtype=dt)
            pos += nbytes
            columns[name] = block.copy() if c == 1 else block.reshape(n, c).copy()
    for name in list(columns):
        if name == '_' or name.startswith('__') or (name.startswith('_') and
                                                    name[1:].replace('_', '').isdigit()):
            del columns[name]
    return columns


def xyz(cloud):
    """(N, 3) float64 positions of a cloud read by read_pcd."""
    return np.stack([cloud['x'], cloud['y'], cloud['z']], axis=1).astype(np.float64)


# ---------------------------------------------------------------------------------------------
# Writing (tests and fixtures)
# ---------------------------------------------------------------------------------------------
def write_pcd(path, columns, data='binary_compressed'):
    """Writes an ordered mapping field name -> 1-D numpy array (all of equal length)."""
    names = list(columns)
    arrays = [np.ascontiguousarray(columns[k]) for k in names]
    n = len(arrays[0]) if arrays else 0
    types, sizes = [], []
    for a in arrays:
        if a.ndim != 1 or len(a) != n:
            raise ValueError('write_pcd: every field must be a 1-D array of the same length')
        kind = {'f': 'F', 'u': 'U', 'i': 'I'}[a.dtype.kind]
        types.append(kind)
        sizes.append(a.dtype.itemsize)
    header = ('# .PCD v0.7 - Point Cloud Data file format\nVERSION 0.7\n'
              'FIELDS %s\nSIZE %s\nTYPE %s\nCOUNT %s\nWIDTH %d\nHEIGHT 1\n'
              'VIEWPOINT 0 0 0 1 0 0 0\nPOINTS %d\nDATA %s\n'
              % (' '.join(names), ' '.join(map(str, sizes)), ' '.join(types),
                 ' '.join(['1'] * len(names)), n, n, data))
    with open(path, 'wb') as f:
        f.write(header.encode('ascii'))
        if data == 'ascii':
            lines = []
            for i in range(n):
                lines.append(' '.join(repr(float(a[i])) if a.dtype.kind == 'f' else str(int(a[i]))
                                      for a in arrays))
            f.write(('\n'.join(lines) + ('\n' if lines else '')).encode('ascii'))
        elif data == 'binary':
            structured = np.empty(n, dtype=[(str(i), a.dtype.newbyteorder('<'))
                                            for i, a in enumerate(arrays)])
            for i, a in enumerate(arrays):
                structured[str(i)] = a
            f.write(structured.tobytes())
        elif data == 'binary_compressed':
            plain = b''.join(a.astype(a.dtype.newbyteorder('<')).tobytes() for a in arrays)
            compressed = lzf_compress(plain) if plain else b''
            f.write(np.array([len(compressed), len(plain)], dtype='<u4').tobytes())
            f.write(compressed)
        else:
            raise ValueError('write_pcd: unknown DATA %s' % data)
