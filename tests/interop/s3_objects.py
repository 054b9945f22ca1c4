"""Objects on an S3-compatible server through boto3, the AWS SDK for Python: the independent
client that puts a campaign's inputs into a bucket and reads its outputs back.

usage: s3_objects.py ENDPOINT put BUCKET PREFIX DIR   (the bucket is made if missing)
       s3_objects.py ENDPOINT get BUCKET PREFIX DIR   (prints how many objects it got)
"""

import sys

import boto3
from object_tree import destination, names


def main(endpoint, op, bucket, prefix, local):
    s3 = boto3.client(
        "s3",
        endpoint_url=endpoint,
        aws_access_key_id="hilrig-test",
        aws_secret_access_key="hilrig-test",
        region_name="us-east-1",
    )
    if op == "put":
        if bucket not in [b["Name"] for b in s3.list_buckets().get("Buckets", [])]:
            s3.create_bucket(Bucket=bucket)
        for path, key in names(local, prefix):
            s3.upload_file(path, bucket, key)
        return 0
    if op == "get":
        n = 0
        for page in s3.get_paginator("list_objects_v2").paginate(Bucket=bucket, Prefix=prefix):
            for o in page.get("Contents", []):
                s3.download_file(bucket, o["Key"], destination(local, prefix, o["Key"]))
                n += 1
        print(n)
        return 0
    print(f"unknown operation {op!r}", file=sys.stderr)
    return 2


if __name__ == "__main__":
    sys.exit(main(*sys.argv[1:]))
