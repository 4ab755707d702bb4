# Times SimpleITK's DICOM series reader on a folder (for BENCHMARKS.md):
#   pip install SimpleITK && python3 examples/itk_series_reader.py SERIES_DIR
import SimpleITK as sitk, time, sys
d=sys.argv[1]
times=[]
for _ in range(5):
    t=time.perf_counter()
    r=sitk.ImageSeriesReader(); files=r.GetGDCMSeriesFileNames(d); r.SetFileNames(files); img=r.Execute()
    times.append(time.perf_counter()-t)
times.sort(); print("SimpleITK", sitk.Version_VersionString(), img.GetSize(), "median %.3f s best %.3f s, %.0f MB/s"%(times[2], times[0], 512*512*400*2/1e6/times[2]))
