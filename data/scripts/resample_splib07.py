"""Resample USGS Spectral Library Version 7 records to the ground-albedo CSVs.

Input: the records as JSON (`wavelengths` in micrometres, `reflectance` as
fractions, null for the library's deleted channels), as the repository
chrislyonsKY/speclib stores them under `docs/data/spectra/`.
Output: `ground_<name>.csv`, `wavelength_nm,albedo` at 5 nm from 360 to 830 nm.

Method: the deleted channels (null or negative) are dropped; each output
wavelength takes the straight line between the two valid source samples that
bracket it (a source sample at the node itself is copied unchanged).
Values are printed to 5 decimals.

Usage: python3 resample_splib07.py SOURCE_DIR OUTPUT_DIR
"""

import json
import sys
from pathlib import Path

RECORDS = {
    "grass": "usgs_splib07_vegetation_lawn_grass_gds91_green_eda96134.json",
    "snow": "usgs_splib07_water_melting_snow_msnw01a_f9d7148f.json",
    "sand": "usgs_splib07_soil_sand_dwo-3-del2ar1_no_oil_30a17c3d.json",
    "ocean": "usgs_splib07_water_seawater_open_ocean_sw2_lwch_20e12608.json",
}


def resample(points, wavelength_nm):
    for (x0, y0), (x1, y1) in zip(points, points[1:]):
        if abs(x0 - wavelength_nm) < 1e-3:
            return y0
        if x0 < wavelength_nm < x1:
            return y0 + (y1 - y0) * (wavelength_nm - x0) / (x1 - x0)
    raise ValueError(f"{wavelength_nm} nm is outside the record")


def main(source_dir, output_dir):
    for name, record in RECORDS.items():
        data = json.loads((Path(source_dir) / record).read_text())
        points = [
            (w * 1000.0, r)
            for w, r in zip(data["wavelengths"], data["reflectance"])
            if r is not None and r >= 0.0
        ]
        rows = ["wavelength_nm,albedo"]
        for wavelength_nm in range(360, 831, 5):
            rows.append(f"{wavelength_nm},{resample(points, wavelength_nm):.5f}")
        (Path(output_dir) / f"ground_{name}.csv").write_text("\n".join(rows) + "\n")


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2])
