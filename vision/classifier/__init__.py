"""The paper's CNN + linear-SVM cell classifier: model, training, loading and batched inference."""
from vision.classifier.inference import DEFAULT_WEIGHTS, CellClassifier, load_classifier, save_weights
from vision.classifier.model import CellCNN, svm_loss
from vision.classifier.preprocess import to_gray_cell, to_input
from vision.classifier.train import TrainConfig, fit

__all__ = ["DEFAULT_WEIGHTS", "CellCNN", "CellClassifier", "TrainConfig", "fit", "load_classifier",
           "save_weights", "svm_loss", "to_gray_cell", "to_input"]
