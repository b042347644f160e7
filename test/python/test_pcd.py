import os
import shutil
import subprocess

import numpy as np
import pytest

from multisession_mapper_eval import pcd

REAL = os.path.join(os.path.dirname(__file__), '..', '..', '..', 'shared', 'data', 'real')


def _cloud(n=500, seed=3):
    rng = np.random.default_rng(seed)
    return {'x': rng.normal(size=n).astype(np.float32),
            'y': rng.normal(size=n).astype(np.float32),
            'z': np.round(rng.normal(size=n), 1).astype(np.float32),
            'intensity': rng.uniform(0, 255, n).astype(np.float32),
            'ring': rng.integers(0, 16, n).astype(np.uint16),
            'label': rng.integers(0, 11, n).astype(np.uint8)}


def test_lzf_known_stream():
    # literal "abc" (ctrl 2), then a back-reference of length 6 at offset 3 (overlapping copy).
    stream = bytes([2]) + b'abc' + bytes([(4 << 5) | 0, 2])
    assert pcd.lzf_decompress(stream, 9) == b'abcabcabc'


_NOISE = np.random.default_rng(1).integers(0, 4, 5000, dtype=np.uint8).tobytes()


@pytest.mark.parametrize('data', [b'', b'a', b'abcabcabcabcabc' * 40, bytes(range(256)) * 50,
                                  _NOISE])
def test_lzf_round_trip(data):
    compressed = pcd.lzf_compress(data)
    assert pcd.lzf_decompress(compressed, len(data)) == data
    if len(data) > 1000 and len(set(data)) < 10:
        assert len(compressed) < len(data)


def test_lzf_rejects_corrupt_stream():
    with pytest.raises(pcd.PcdError):
        pcd.lzf_decompress(bytes([(1 << 5) | 0, 200]), 3)  # reference before the start
    with pytest.raises(pcd.PcdError):
        pcd.lzf_decompress(bytes([5]) + b'ab', 6)  # truncated literal


@pytest.mark.parametrize('data', ['ascii', 'binary', 'binary_compressed'])
def test_write_read_round_trip(tmp_path, data):
    cloud = _cloud()
    path = str(tmp_path / ('c_%s.pcd' % data))
    pcd.write_pcd(path, cloud, data=data)
    back = pcd.read_pcd(path)
    assert list(back) == list(cloud)
    for key in cloud:
        assert back[key].dtype == cloud[key].dtype
        np.testing.assert_array_equal(back[key], cloud[key])
    assert pcd.read_pcd_header(path).points == 500
    np.testing.assert_allclose(pcd.xyz(back)[:, 2], cloud['z'])


def test_truncated_file_names_the_file(tmp_path):
    path = str(tmp_path / 'broken.pcd')
    pcd.write_pcd(path, _cloud(), data='binary_compressed')
    raw = open(path, 'rb').read()
    with open(path, 'wb') as f:
        f.write(raw[:-40])
    with pytest.raises(pcd.PcdError, match='broken.pcd'):
        pcd.read_pcd(path)


@pytest.mark.skipif(shutil.which('pcl_convert_pcd_ascii_binary') is None,
                    reason='pcl_convert_pcd_ascii_binary (Debian pcl-tools) not installed')
@pytest.mark.parametrize('mode', [0, 1, 2])
def test_reads_files_written_by_pcl(tmp_path, mode):
    cloud = _cloud(n=3000)
    source = str(tmp_path / 'source.pcd')
    pcd.write_pcd(source, cloud, data='ascii')
    converted = str(tmp_path / ('pcl_%d.pcd' % mode))
    subprocess.run(['pcl_convert_pcd_ascii_binary', source, converted, str(mode)], check=True,
                   stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    expected = {0: 'ascii', 1: 'binary', 2: 'binary_compressed'}[mode]
    assert pcd.read_pcd_header(converted).data == expected
    back = pcd.read_pcd(converted)
    for key in cloud:
        np.testing.assert_allclose(back[key].astype(float), cloud[key].astype(float),
                                   rtol=1e-6, atol=1e-6)


@pytest.mark.skipif(shutil.which('pcl_convert_pcd_ascii_binary') is None,
                    reason='pcl_convert_pcd_ascii_binary (Debian pcl-tools) not installed')
def test_our_compressed_file_is_readable_by_pcl(tmp_path):
    cloud = _cloud(n=2000)
    ours = str(tmp_path / 'ours.pcd')
    pcd.write_pcd(ours, cloud, data='binary_compressed')
    ascii_path = str(tmp_path / 'back.pcd')
    subprocess.run(['pcl_convert_pcd_ascii_binary', ours, ascii_path, '0'], check=True,
                   stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    back = pcd.read_pcd(ascii_path)
    np.testing.assert_allclose(back['x'], cloud['x'], rtol=1e-6)
    np.testing.assert_array_equal(back['ring'], cloud['ring'])


def test_real_vlp16_binary_with_padding():
    path = os.path.join(REAL, 'vlp16_indoor', '0.pcd')
    if not os.path.isfile(path):
        pytest.skip('../shared/data/real/vlp16_indoor absent (only on the CI machine)')
    cloud = pcd.read_pcd(path)
    assert list(cloud) == ['x', 'y', 'z', 'intensity', 'ring']  # padding `_` dropped
    assert len(cloud['x']) == pcd.read_pcd_header(path).points
    assert set(np.unique(cloud['ring'])) == set(range(16))
    ranges = np.linalg.norm(pcd.xyz(cloud), axis=1)
    assert np.all(np.isfinite(ranges)) and 0.3 < np.median(ranges) < 30.0
