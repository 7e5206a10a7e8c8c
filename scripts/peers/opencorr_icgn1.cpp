// livedic bench peers: OpenCorr's FFT-CC + IC-GN (first order, bicubic B-spline), as its example
// test_2d_dic_fftcc_icgn1.cpp, on images read at full bit depth (8- or 16-bit PNG/TIFF).
// usage: opencorr_icgn1 REF TAR POIS.csv OUT.csv SUBSET_RADIUS [MAX_ITER=10] [NORM=0.001] [THREADS=1]
// POIS.csv: one "x,y" per line (pixels). OUT.csv: x,y,u,v,zncc,iteration,convergence (zncc < 0: failed).
// OpenCorr's own Image2D loader reads with IMREAD_GRAYSCALE, which cuts 12/16-bit images to 8 bit: the images
// are read here unchanged and handed to it as float.
#include <fstream>
#include <sstream>
#include <omp.h>
#include "oc_fftcc.h"
#include "oc_icgn.h"
#include "oc_image.h"

using namespace opencorr;

static Image2D load_full_depth(const std::string& path)
{
	cv::Mat raw = cv::imread(path, cv::IMREAD_UNCHANGED);
	if (!raw.data || raw.channels() != 1) throw std::string("cannot read a grey image: " + path);
	Image2D image(raw.cols, raw.rows);
	image.file_path = path;
	cv::Mat as_float;
	raw.convertTo(as_float, CV_32F);
	cv::cv2eigen(as_float, image.eg_mat);
	return image;
}

int main(int argc, char** argv)
{
	if (argc < 6) { std::cerr << "usage: opencorr_icgn1 REF TAR POIS.csv OUT.csv SUBSET_RADIUS [MAX_ITER] [NORM] [THREADS]\n"; return 2; }
	try {
		Image2D ref_img = load_full_depth(argv[1]);
		Image2D tar_img = load_full_depth(argv[2]);
		int radius = std::stoi(argv[5]);
		int max_iteration = argc > 6 ? std::stoi(argv[6]) : 10;
		float max_norm = argc > 7 ? std::stof(argv[7]) : 0.001f;
		int threads = argc > 8 ? std::stoi(argv[8]) : 1;
		omp_set_num_threads(threads);
		std::vector<POI2D> pois;
		std::ifstream in(argv[3]);
		std::string line;
		while (std::getline(in, line)) {
			std::stringstream cells(line);
			float x, y; char comma;
			if (cells >> x >> comma >> y) pois.push_back(POI2D(x, y));
		}
		FFTCC2D fftcc(radius, radius, threads);
		fftcc.setImages(ref_img, tar_img);
		fftcc.compute(pois);
		ICGN2D1 icgn(radius, radius, max_norm, max_iteration, threads);
		icgn.setImages(ref_img, tar_img);
		icgn.prepare();
		icgn.compute(pois);
		std::ofstream out(argv[4]);
		out.precision(9);
		out << "x,y,u,v,zncc,iteration,convergence\n";
		for (auto& p : pois)
			out << p.x << "," << p.y << "," << p.deformation.u << "," << p.deformation.v << "," << p.result.zncc
			    << "," << p.result.iteration << "," << p.result.convergence << "\n";
	} catch (const std::string& error) { std::cerr << error << "\n"; return 1; }
	return 0;
}
