import io
import zipfile

import numpy as np

from mirrorgraph.io.archive import savez


def test_every_member_reads_back_floats_stored_the_rest_deflated():
    rng = np.random.default_rng(0)
    arrays = {"joints3d": rng.normal(size=(50, 17, 3)), "valid": rng.random((50, 17)) > 0.1,
              "frame_ids": np.arange(50, dtype=np.int64), "names": np.array(["a", "bb"]),
              "fps": np.float64(30.0)}
    buf = io.BytesIO()
    savez(buf, arrays)
    with np.load(io.BytesIO(buf.getvalue())) as z:
        assert sorted(z.files) == sorted(arrays)
        for k, v in arrays.items():
            np.testing.assert_array_equal(z[k], v)
    kinds = {i.filename: i.compress_type for i in zipfile.ZipFile(buf).infolist()}
    assert kinds["joints3d.npy"] == kinds["fps.npy"] == zipfile.ZIP_STORED
    assert kinds["valid.npy"] == kinds["frame_ids.npy"] == zipfile.ZIP_DEFLATED
    again = io.BytesIO()
    savez(again, arrays)
    assert again.getvalue() == buf.getvalue()          # the data alone decide the bytes
