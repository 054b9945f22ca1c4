"""Blobs on Azurite (Microsoft's Azure Storage emulator) through azure-storage-blob, the Azure
SDK for Python: the independent client that puts a campaign's inputs into a container and reads
its outputs back. The account is the emulator's well-known development account.

usage: azure_objects.py ENDPOINT put CONTAINER PREFIX DIR   (the container is made if missing)
       azure_objects.py ENDPOINT get CONTAINER PREFIX DIR   (prints how many blobs it got)
"""

import sys

from azure.storage.blob import BlobServiceClient
from object_tree import destination, names

# Azurite's development account and key (public, the same in every emulator).
ACCOUNT = "devstoreaccount1"
KEY = "Eby8vdM02xNOcqFlqUwJPLlmEtlCDXJ1OUzFT50uSRZ6IFsuFq2UVErCz4I6tq/K1SZFPTOtr/KBHBeksoGMGw=="


def main(endpoint, op, container, prefix, local):
    service = BlobServiceClient.from_connection_string(
        f"DefaultEndpointsProtocol=http;AccountName={ACCOUNT};AccountKey={KEY};"
        f"BlobEndpoint={endpoint}/{ACCOUNT};"
    )
    c = service.get_container_client(container)
    if op == "put":
        if not c.exists():
            c.create_container()
        for path, name in names(local, prefix):
            with open(path, "rb") as data:
                c.upload_blob(name, data, overwrite=True)
        return 0
    if op == "get":
        n = 0
        for b in c.list_blobs(name_starts_with=prefix):
            with open(destination(local, prefix, b.name), "wb") as f:
                f.write(c.download_blob(b.name).readall())
            n += 1
        print(n)
        return 0
    print(f"unknown operation {op!r}", file=sys.stderr)
    return 2


if __name__ == "__main__":
    sys.exit(main(*sys.argv[1:]))
